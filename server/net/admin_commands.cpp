// The session's admin commands (docs/PROTOCOL.md 4.11): the player list, kicks and bans,
// for admins only. Bans are stored by the BanKeeper and answered once stored; the rest is
// answered at once. Strand only, but where a comment says otherwise.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/net/address_key.hpp"
#include "server/net/client_session.hpp"

namespace vox::net {

namespace {

using Ban = store::Ban;

constexpr size_t kListPageBytes = 32 * 1024;  // a players page stops near this size
constexpr size_t kBansPerPage = 100;          // ~40 KB at most
constexpr uint64_t kMaxBanSeconds = 100ull * 366 * 24 * 3600;

// The player id or address a Kick or Ban names (exactly one); an address as admission
// counts it (an IPv6 one: its /64). Or why not.
struct Target {
  std::optional<std::pair<Ban::Kind, std::string>> who;
  std::string problem;
};
Target target_of(const std::string& player_id, const std::string& address) {
  if (player_id.empty() == address.empty())
    return {std::nullopt, "name exactly one of a player id and an address"};
  if (!player_id.empty()) {
    Ban probe;
    probe.target = player_id;
    if (auto why = store::ban_problem(probe)) return {std::nullopt, *why};
    return {std::make_pair(Ban::Kind::kPlayer, player_id), ""};
  }
  std::optional<std::string> key = address_key_of(address);
  if (!key) return {std::nullopt, "'" + escape_for_log(address, 64) + "' is not an IP address"};
  return {std::make_pair(Ban::Kind::kAddress, std::move(*key)), ""};
}

wire::Ban to_wire(const Ban& b) {
  wire::Ban w;
  (b.kind == Ban::Kind::kPlayer ? *w.mutable_player_id() : *w.mutable_address()) = b.target;
  w.set_reason(b.reason);
  w.set_until_unix_ms(b.until_ms);
  w.set_created_by(b.created_by);
  w.set_created_unix_ms(b.created_ms);
  return w;
}

wire::AdminResult::Status status_of(BanKeeper::Outcome::Status s) {
  using S = BanKeeper::Outcome::Status;
  switch (s) {
    case S::kOk:
      return wire::AdminResult::OK;
    case S::kNotFound:
      return wire::AdminResult::NOT_FOUND;
    case S::kTooMany:
      return wire::AdminResult::TOO_MANY;
    case S::kUnavailable:
      return wire::AdminResult::STORAGE_UNAVAILABLE;
    case S::kBusy:
    case S::kStopped:
      break;
  }
  return wire::AdminResult::BUSY;
}

}  // namespace

size_t close_matching(SessionDirectory<ClientSession>& sessions, Ban::Kind kind,
                      const std::string& target, wire::Error::Code code, const std::string& message,
                      int64_t banned_until_unix_ms, uint64_t except_session,
                      bool spare_admins) {  // any thread
  size_t closed = 0;
  for (const auto& s : sessions.live()) {
    const std::optional<PlayerCard> card = s->card();
    if (!card || card->session == except_session) continue;
    if (spare_admins && card->role == auth::Role::kAdmin) continue;
    if ((kind == Ban::Kind::kPlayer ? card->player_id : card->address) != target) continue;
    s->close_with_error(code, message, banned_until_unix_ms);
    ++closed;
  }
  return closed;
}

void ClientSession::handle_admin_command(const wire::AdminCommand& command) {
  wire::Envelope reply;
  auto* result = reply.mutable_admin_result();
  result->set_request_id(command.request_id());
  if (role_ != auth::Role::kAdmin) {
    if (auto suppressed = services_.logs->allow("admin-refused", 5)) {
      spdlog::warn("session {}: player '{}' ({}, {}) may not list, kick, ban or roll back{}", id_,
                   log_name_, player_id_.empty() ? "no id" : escape_for_log(player_id_),
                   auth::to_string(role_),
                   *suppressed ? fmt::format(" [{} more refused]", *suppressed) : std::string());
    }
    result->set_status(wire::AdminResult::FORBIDDEN);
    result->set_reason("only an admin may list, kick or ban players, or roll edits back");
    return queue_control(reply);
  }
  switch (command.command_case()) {
    case wire::AdminCommand::kPlayers:
      return list_players(command.players().after_session(), reply);
    case wire::AdminCommand::kKick:
      return kick(command.kick(), reply);
    case wire::AdminCommand::kBan:
      return ban(command.ban(), reply);
    case wire::AdminCommand::kUnban:
      return unban(command.unban(), reply);
    case wire::AdminCommand::kBans:
      return list_bans(command.bans().cursor(), reply);
    case wire::AdminCommand::kRollback:
      return rollback(command.rollback(), reply);
    default:
      break;
  }
  result->set_status(wire::AdminResult::BAD_VALUE);
  result->set_reason("the AdminCommand carries no command");
  queue_control(reply);
}

void ClientSession::list_players(uint64_t after_session, wire::Envelope& reply) {
  std::vector<PlayerCard> cards;
  for (const auto& s : services_.sessions->live())
    if (auto c = s->card(); c && c->session > after_session) cards.push_back(std::move(*c));
  std::sort(cards.begin(), cards.end(),
            [](const PlayerCard& a, const PlayerCard& b) { return a.session < b.session; });
  auto* result = reply.mutable_admin_result();
  size_t bytes = 0, i = 0;
  for (; i < cards.size() && bytes < kListPageBytes; ++i) {
    const PlayerCard& c = cards[i];
    auto* p = result->add_players();
    p->set_session(c.session);
    p->set_player_id(c.player_id);
    p->set_name(c.name);
    p->set_role(auth::to_string(c.role));
    p->set_address(c.address);
    p->set_connected_unix_ms(c.connected_unix_ms);
    p->set_edits(c.edits);
    p->set_bytes_sent(c.bytes_sent);
    bytes += p->ByteSizeLong();
  }
  result->set_more(i < cards.size());
  result->set_status(wire::AdminResult::OK);
  queue_control(reply);
}

void ClientSession::kick(const wire::Kick& kick, wire::Envelope& reply) {
  auto* result = reply.mutable_admin_result();
  const Target t = target_of(kick.player_id(), kick.address());
  std::optional<std::string> problem = t.who ? std::nullopt : std::optional(t.problem);
  if (!problem && kick.reason().size() > store::kMaxBanReason)
    problem = "a kick's reason is at most " + std::to_string(store::kMaxBanReason) + " bytes";
  if (!problem && std::any_of(kick.reason().begin(), kick.reason().end(), [](char c) {
        return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
      }))
    problem = "a kick's reason holds no control characters";
  if (problem) {
    result->set_status(wire::AdminResult::BAD_VALUE);
    result->set_reason(*problem);
    return queue_control(reply);
  }
  const auto& [kind, target] = *t.who;
  const size_t closed = close_matching(
      *services_.sessions, kind, target, wire::Error::KICKED,
      kick.reason().empty() ? "kicked by an admin" : "kicked: " + kick.reason(), 0, id_, false);
  log_admin(fmt::format("kicked {} {} ({} connections){}", store::to_string(kind),
                        escape_for_log(target), closed,
                        kick.reason().empty() ? "" : ": " + escape_for_log(kick.reason())));
  result->set_kicked(static_cast<uint32_t>(closed));
  const bool only_itself = (kind == Ban::Kind::kPlayer ? player_id_ : address_) == target;
  if (closed == 0) {
    result->set_status(only_itself ? wire::AdminResult::BAD_VALUE : wire::AdminResult::NOT_FOUND);
    result->set_reason(only_itself
                           ? "an admin's command never closes its own connection"
                           : std::string("no connection of that ") + store::to_string(kind));
  } else {
    result->set_status(wire::AdminResult::OK);
  }
  queue_control(reply);
}

void ClientSession::ban(const wire::Ban& request, wire::Envelope& reply) {
  auto* result = reply.mutable_admin_result();
  const Target t = target_of(request.player_id(), request.address());
  Ban b;
  if (t.who) {
    b.kind = t.who->first, b.target = t.who->second;
    b.reason = request.reason();
    b.created_by = player_id_.empty() ? "name:" + name_ : player_id_;
    b.created_ms = BanKeeper::now_ms();
    b.until_ms =
        request.duration_seconds() == 0
            ? 0
            : b.created_ms +
                  static_cast<int64_t>(std::min(request.duration_seconds(), kMaxBanSeconds)) * 1000;
  }
  std::optional<std::string> problem = t.who ? store::ban_problem(b) : t.problem;
  if (!problem && b.kind == Ban::Kind::kPlayer && b.target == player_id_)
    problem = "an admin may not ban its own player id (it could not connect to lift the ban)";
  if (!problem && request.duration_seconds() > kMaxBanSeconds)
    problem = "a ban lasts at most 100 years (duration 0: until unbanned)";
  if (!problem && admin_commands_in_flight_ >= kMaxAdminCommandsInFlight)
    problem = "over " + std::to_string(kMaxAdminCommandsInFlight) + " ban commands waiting";
  if (problem) {
    result->set_status(problem->starts_with("over ") ? wire::AdminResult::BUSY
                                                     : wire::AdminResult::BAD_VALUE);
    result->set_reason(*problem);
    return queue_control(reply);
  }
  ++admin_commands_in_flight_;
  services_.bans->put(b, [self = shared_from_this(), reply](const BanKeeper::Outcome& out) {
    // The keeper's thread: close the banned player's connections, answer on the strand.
    asio::post(self->strand_, [self, reply, out]() mutable {
      --self->admin_commands_in_flight_;
      auto* r = reply.mutable_admin_result();
      r->set_status(status_of(out.status));
      r->set_reason(out.message);
      if (out.status != BanKeeper::Outcome::Status::kOk) return self->queue_control(reply);
      const size_t closed = close_matching(
          *self->services_.sessions, out.ban.kind, out.ban.target, wire::Error::BANNED,
          describe_ban(out.ban), out.ban.until_ms, self->id_, out.ban.kind == Ban::Kind::kAddress);
      *r->add_bans() = to_wire(out.ban);
      r->set_kicked(static_cast<uint32_t>(closed));
      self->log_admin(fmt::format("banned {} {} ({} connections closed): {}",
                                  store::to_string(out.ban.kind), escape_for_log(out.ban.target),
                                  closed, escape_for_log(describe_ban(out.ban))));
      self->queue_control(reply);
    });
  });
}

void ClientSession::unban(const wire::Ban& request, wire::Envelope& reply) {
  auto* result = reply.mutable_admin_result();
  const Target t = target_of(request.player_id(), request.address());
  if (!t.who || admin_commands_in_flight_ >= kMaxAdminCommandsInFlight) {
    result->set_status(t.who ? wire::AdminResult::BUSY : wire::AdminResult::BAD_VALUE);
    result->set_reason(t.who ? "over " + std::to_string(kMaxAdminCommandsInFlight) +
                                   " ban commands waiting"
                             : t.problem);
    return queue_control(reply);
  }
  ++admin_commands_in_flight_;
  services_.bans->remove(
      t.who->first, t.who->second,
      [self = shared_from_this(), reply](const BanKeeper::Outcome& out) {
        asio::post(self->strand_, [self, reply, out]() mutable {
          --self->admin_commands_in_flight_;
          auto* r = reply.mutable_admin_result();
          r->set_status(status_of(out.status));
          r->set_reason(out.message);
          if (out.status == BanKeeper::Outcome::Status::kOk) {
            *r->add_bans() = to_wire(out.ban);
            self->log_admin(fmt::format("unbanned {} {}", store::to_string(out.ban.kind),
                                        escape_for_log(out.ban.target)));
          }
          self->queue_control(reply);
        });
      });
}

void ClientSession::list_bans(const std::string& cursor, wire::Envelope& reply) {
  auto* result = reply.mutable_admin_result();
  const BanBook::Page page = services_.bans->page(cursor.substr(0, 256), kBansPerPage);
  for (const Ban& b : page.bans) *result->add_bans() = to_wire(b);
  result->set_more(!page.next.empty());
  result->set_cursor(page.next);
  result->set_status(wire::AdminResult::OK);
  queue_control(reply);
}

// A rollback (pipeline/rollbacks.hpp), answered once done. At least one filter: a slip of
// the hand must not undo the whole world.
void ClientSession::rollback(const wire::Rollback& request, wire::Envelope& reply) {
  auto* result = reply.mutable_admin_result();
  store::RollbackQuery q;
  std::string problem;
  if (request.undo_rollback() != 0) {
    q.undo_record = request.undo_rollback();
    if (!request.player_id().empty() || request.has_box() || request.since_unix_ms() != 0 ||
        request.until_unix_ms() != 0)
      problem = "undo_rollback takes no filter";
  } else {
    q.player = request.player_id();
    if (q.player.size() > 128) problem = "a player id is at most 128 bytes";
    if (std::any_of(q.player.begin(), q.player.end(),
                    [](unsigned char c) { return c < 0x20 || c == 0x7f; }))
      problem = "a player id holds no control characters";
    if (request.has_box()) {
      const wire::VoxelBox& b = request.box();
      q.box = world::VoxelBox{{b.min_x(), b.min_y(), b.min_z()}, {b.max_x(), b.max_y(), b.max_z()}};
      for (int a = 0; a < 3; ++a)
        if (q.box->lo[a] > q.box->hi[a]) problem = "the box's min exceeds its max";
    }
    if (request.since_unix_ms() < 0 || request.until_unix_ms() < 0) problem = "a time before 1970";
    if (request.since_unix_ms() != 0) q.since_ms = request.since_unix_ms();
    if (request.until_unix_ms() != 0) q.until_ms = request.until_unix_ms();
    if (request.until_unix_ms() != 0 && q.until_ms <= q.since_ms)
      problem = "until is not after since";
    if (q.player.empty() && !q.box && request.since_unix_ms() == 0)
      problem =
          "name a player, a box or a time (a rollback of everyone's edits everywhere is "
          "refused)";
  }
  if (problem.empty() && admin_commands_in_flight_ >= kMaxAdminCommandsInFlight)
    problem = "over " + std::to_string(kMaxAdminCommandsInFlight) + " admin commands waiting";
  if (!problem.empty()) {
    result->set_status(problem.starts_with("over") ? wire::AdminResult::BUSY
                                                   : wire::AdminResult::BAD_VALUE);
    result->set_reason(problem);
    return queue_control(reply);
  }
  ++admin_commands_in_flight_;
  const std::string what =
      q.undo_record
          ? fmt::format("undo of rollback {}", q.undo_record)
          : fmt::format("rollback of '{}'{}{}", escape_for_log(q.player, 64),
                        q.box ? " in a box" : "", request.since_unix_ms() ? " since a time" : "");
  const bool dry_run = request.dry_run();
  pipeline_.rollback({.query = std::move(q),
                      .dry_run = dry_run,
                      .by = player_id_,
                      .done = [self = shared_from_this(), reply, what,
                               dry_run](const pipeline::RollbackReport& out) mutable {
                        asio::post(self->strand_, [self, reply, what, dry_run, out]() mutable {
                          --self->admin_commands_in_flight_;
                          using S = pipeline::RollbackReport::Status;
                          auto* r = reply.mutable_admin_result();
                          r->set_status(out.status == S::kOk        ? wire::AdminResult::OK
                                        : out.status == S::kRefused ? wire::AdminResult::BAD_VALUE
                                        : out.status == S::kTooMany ? wire::AdminResult::TOO_MANY
                                        : out.status == S::kUnavailable
                                            ? wire::AdminResult::STORAGE_UNAVAILABLE
                                            : wire::AdminResult::BUSY);
                          r->set_reason(out.message);
                          auto* w = r->mutable_rollback();
                          w->set_record(out.record);
                          w->set_edits(out.edits);
                          w->set_chunks(out.chunks);
                          w->set_history_from(out.history_from);
                          w->set_history_from_unix_ms(out.history_from_ms);
                          w->set_seconds(out.seconds);
                          if (out.status == S::kOk && !dry_run)
                            self->log_admin(fmt::format("{}: {} edits, {} chunks, record {}", what,
                                                        out.edits, out.chunks, out.record));
                          self->queue_control(reply);
                        });
                      }});
}

// Every admin action, one line with its author (a few per second at most, with a count).
void ClientSession::log_admin(const std::string& what) {
  if (auto suppressed = services_.logs->allow("admin", 20)) {
    spdlog::info(
        "session {}: admin '{}' ({}) {}{}", id_, log_name_,
        player_id_.empty() ? "no id" : escape_for_log(player_id_), what,
        *suppressed ? fmt::format(" [{} more admin actions]", *suppressed) : std::string());
  }
}

}  // namespace vox::net
