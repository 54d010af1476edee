// voxel-cli players | kick | ban | unban | bans | rollback: an admin's view of who is on,
// keeping griefers out and undoing what they did, over the protocol (docs/PROTOCOL.md 4.11,
// 4.12), with an admin token (--token or VOXEL_TOKEN).
#include <algorithm>
#include <charconv>
#include <cstdio>
#include <ctime>
#include <limits>
#include <ostream>

#include "client-cli/commands.hpp"
#include "client-cli/edit_filter.hpp"
#include "client-cli/server_request.hpp"

namespace vox::cli {
namespace {

constexpr const char* kSynopsis =
    "usage: voxel-cli players\n"
    "       voxel-cli kick PLAYER_ID|ADDRESS [--reason TEXT]\n"
    "       voxel-cli ban PLAYER_ID|ADDRESS [--for DURATION] [--reason TEXT]\n"
    "       voxel-cli unban PLAYER_ID|ADDRESS\n"
    "       voxel-cli bans\n"
    "       voxel-cli rollback [--player ID] [--min X,Y,Z --max X,Y,Z] [--since T] [--until T]\n"
    "                          [--dry-run]\n"
    "       voxel-cli rollback --undo SEQ [--dry-run]\n"
    "(with an admin token: --token or VOXEL_TOKEN; a target that parses as an IP address is "
    "an address, an IPv6 one bans its /64; --address or --player say which)";

wire::AdminResult ask(const po::variables_map& vm, wire::Envelope command) {
  command.mutable_admin_command()->set_request_id(1);
  return server_request(
             vm, command,
             [](const wire::Envelope& m) {
               return m.has_admin_result() && m.admin_result().request_id() == 1;
             },
             "AdminResult")
      .admin_result();
}

std::string utc(int64_t unix_ms) {
  const std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char s[32];
  std::strftime(s, sizeof s, "%Y-%m-%d %H:%M:%S", &tm);
  return s;
}

// "203.0.113.7", "2001:db8::5", "2001:db8::/64" (as `bans` and `players` print an IPv6
// client): a player id has letters beyond these, or no dots and colons.
bool looks_like_address(const std::string& t) {
  return !t.empty() && t.find_first_not_of("0123456789abcdefABCDEF.:/") == std::string::npos &&
         (std::count(t.begin(), t.end(), '.') == 3 || t.find(':') != std::string::npos);
}

// A player's name as the terminal should show it: control characters as \xNN (an open
// server takes any name; it must not drive the admin's terminal).
std::string printable(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    if (c < 0x20 || c == 0x7f || c == '\\') {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

// The target of kick, ban and unban into a Kick's or Ban's player_id / address.
template <typename Message>
void set_target(const po::variables_map& vm, Message& m) {
  const std::string target = vm["target"].as<std::string>();
  const bool address =
      vm["address"].as<bool>() || (!vm["player"].as<bool>() && looks_like_address(target));
  (address ? *m.mutable_address() : *m.mutable_player_id()) = target;
}

std::string describe(const wire::Ban& b) {
  std::string s = b.player_id().empty() ? "address " + b.address() : "player " + b.player_id();
  s += b.until_unix_ms() == 0 ? "  forever" : "  until " + utc(b.until_unix_ms()) + " UTC";
  s += "  by " + (b.created_by().empty() ? std::string("?") : b.created_by());
  s += " at " + utc(b.created_unix_ms()) + " UTC";
  if (!b.reason().empty()) s += "  reason: " + b.reason();
  return s;
}

int refused(const wire::AdminResult& r, std::ostream& err) {
  err << "voxel-cli: refused: " << wire::AdminResult::Status_Name(r.status()) << ": " << r.reason()
      << "\n";
  return 1;
}

int list_players(const po::variables_map& vm, std::ostream& out, std::ostream& err) {
  wire::Envelope m;
  uint64_t after = 0;
  size_t count = 0;
  out << "session  player id  name  role  address  connected (UTC)  edits  bytes sent\n";
  for (;;) {
    m.mutable_admin_command()->mutable_players()->set_after_session(after);
    const wire::AdminResult r = ask(vm, m);
    if (r.status() != wire::AdminResult::OK) return refused(r, err);
    for (const wire::PlayerInfo& p : r.players()) {
      out << p.session() << "  " << (p.player_id().empty() ? "-" : printable(p.player_id()))
          << "  '" << printable(p.name()) << "'  " << p.role() << "  " << p.address() << "  "
          << utc(p.connected_unix_ms()) << "  " << p.edits() << "  " << p.bytes_sent() << "\n";
      after = p.session();
    }
    count += static_cast<size_t>(r.players_size());
    if (!r.more() || r.players_size() == 0) break;
  }
  out << count << " connected (this command's own connection included)\n";
  return 0;
}

int list_bans(const po::variables_map& vm, std::ostream& out, std::ostream& err) {
  wire::Envelope m;
  std::string cursor;
  size_t count = 0;
  for (;;) {
    m.mutable_admin_command()->mutable_bans()->set_cursor(cursor);
    const wire::AdminResult r = ask(vm, m);
    if (r.status() != wire::AdminResult::OK) return refused(r, err);
    for (const wire::Ban& b : r.bans()) out << describe(b) << "\n";
    count += static_cast<size_t>(r.bans_size());
    if (!r.more() || r.cursor().empty()) break;
    cursor = r.cursor();
  }
  out << count << " ban" << (count == 1 ? "" : "s") << " in force\n";
  return 0;
}

// A rollback on the running server: what it undid (or would), then how far back its
// history reaches.
int rollback(const po::variables_map& vm, std::ostream& out, std::ostream& err) {
  wire::Envelope m;
  auto* rb = m.mutable_admin_command()->mutable_rollback();
  rb->set_dry_run(vm["dry-run"].as<bool>());
  if (vm.count("undo")) {
    if (vm.count("player") || vm.count("min") || vm.count("since") || vm.count("until"))
      throw std::invalid_argument("rollback: --undo takes no filter");
    rb->set_undo_rollback(vm["undo"].as<uint64_t>());
  } else {
    const EditFilter f = parse_edit_filter(vm, "rollback");
    if (f.player) rb->set_player_id(*f.player);
    if (f.box) {
      auto* b = rb->mutable_box();
      b->set_min_x(f.box->lo[0]), b->set_min_y(f.box->lo[1]), b->set_min_z(f.box->lo[2]);
      b->set_max_x(f.box->hi[0]), b->set_max_y(f.box->hi[1]), b->set_max_z(f.box->hi[2]);
    }
    if (vm.count("since")) rb->set_since_unix_ms(std::max<int64_t>(f.since_ms, 1));
    if (vm.count("until"))
      rb->set_until_unix_ms(f.until_ms == std::numeric_limits<int64_t>::max() ? f.until_ms
                                                                              : f.until_ms + 1);
  }
  const wire::AdminResult r = ask(vm, m);
  const wire::RollbackReport& w = r.rollback();
  if (r.status() != wire::AdminResult::OK) {
    refused(r, err);
    if (w.history_from() != 0)
      err << "the history reaches back to edit " << w.history_from() << " ("
          << utc(w.history_from_unix_ms()) << " UTC)\n";
    return 1;
  }
  if (w.edits() == 0) {
    out << "nothing to roll back: no edit in the history matches (or they are rolled back "
           "already)\n";
  } else if (rb->dry_run()) {
    out << "dry run: would " << (rb->undo_rollback() ? "bring back " : "undo ") << w.edits()
        << " edit(s), recomputing " << w.chunks() << " chunk(s)\n";
  } else {
    out << (rb->undo_rollback() ? "brought back " : "rolled back ") << w.edits()
        << " edit(s), recomputed " << w.chunks() << " chunk(s) in " << w.seconds()
        << " s: rollback " << w.record() << " (voxel-cli rollback --undo " << w.record()
        << " undoes it)\n";
  }
  if (w.history_from() != 0)
    out << "the history reaches back to edit " << w.history_from() << " ("
        << utc(w.history_from_unix_ms()) << " UTC)\n";
  return 0;
}

}  // namespace

int admin_command(const std::string& action, const std::vector<std::string>& args,
                  std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options(action);
  const bool targeted = action == "kick" || action == "ban" || action == "unban";
  if (targeted) {
    opts.add_options()("target", po::value<std::string>()->required(),
                       "a player id, or an IP address")(
        "player", po::bool_switch(),
        "the target is a player id (even if it looks like an address)")(
        "address", po::bool_switch(), "the target is an address");
  }
  if (action == "kick" || action == "ban")
    opts.add_options()("reason", po::value<std::string>()->default_value(""),
                       "told to the player and kept with the ban (at most 200 bytes)");
  if (action == "ban")
    opts.add_options()("for", po::value<std::string>(),
                       "how long: 90s, 30m, 12h, 7d, 2w (default: until unbanned)");
  if (action == "rollback") {
    add_edit_filter_options(opts, "rollback");
    opts.add_options()("since", po::value<std::string>(),
                       "rollback: edits accepted at or after this time (2026-12-07T10:30:00, "
                       "UTC) or this long ago (30m, 2h, 7d)")(
        "undo", po::value<uint64_t>(), "undo the rollback of this number (its edits come back)")(
        "dry-run", po::bool_switch(), "say what it would change; change nothing");
  }
  po::positional_options_description positional;
  if (targeted) positional.add("target", 1);
  po::variables_map vm;
  const int rc = parse_options(args, opts, &positional, kSynopsis, vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&]() -> int {
    if (targeted && vm["player"].as<bool>() && vm["address"].as<bool>())
      throw std::invalid_argument("--player and --address exclude each other");
    if (action == "players") return list_players(vm, out, err);
    if (action == "bans") return list_bans(vm, out, err);
    if (action == "rollback") return rollback(vm, out, err);
    wire::Envelope m;
    auto* command = m.mutable_admin_command();
    if (action == "kick") {
      set_target(vm, *command->mutable_kick());
      command->mutable_kick()->set_reason(vm["reason"].as<std::string>());
    } else if (action == "ban") {
      set_target(vm, *command->mutable_ban());
      command->mutable_ban()->set_reason(vm["reason"].as<std::string>());
      if (vm.count("for"))
        command->mutable_ban()->set_duration_seconds(
            options::parse_duration_s(vm["for"].as<std::string>(), "--for"));
    } else {
      set_target(vm, *command->mutable_unban());
    }
    const wire::AdminResult r = ask(vm, m);
    if (r.status() != wire::AdminResult::OK) return refused(r, err);
    if (action == "kick") out << "kicked " << r.kicked() << " connection(s)\n";
    for (const wire::Ban& b : r.bans())
      out << (action == "ban" ? "banned " : "unbanned ") << describe(b) << "\n";
    if (action == "ban") out << r.kicked() << " connection(s) closed\n";
    return 0;
  });
}

}  // namespace vox::cli
