// voxel-cli world info|log|verify WORLD: the durable world as an operator inspects it. Opens
// the store read-only (a world directory or a postgresql:// URI), so it works beside a
// running voxeld.
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <ctime>
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <sstream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/edit_filter.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/edit_codec.hpp"
#include "server/store/world_backup.hpp"
#include "server/store/world_history.hpp"
#include "server/store/world_store.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/edit_replay.hpp"
#include "server/world/edit_undo.hpp"

namespace vox::cli {
namespace {

std::string utc_time(int64_t unix_ms) {
  const std::time_t s = static_cast<std::time_t>(unix_ms / 1000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  std::ostringstream o;
  o << std::put_time(&tm, "%Y-%m-%dT%H:%M:%S") << '.' << std::setw(3) << std::setfill('0')
    << unix_ms % 1000 << 'Z';
  return o.str();
}

// `records`: the rollback records listed so far (a record undoing one is an undo).
std::string describe_rollback(const std::vector<uint64_t>& undoes,
                              const std::set<uint64_t>& records) {
  if (std::all_of(undoes.begin(), undoes.end(), [&](uint64_t s) { return records.count(s); }))
    return "undo of rollback " + std::to_string(undoes.front()) +
           (undoes.size() == 1 ? "" : " and more");
  std::string out = "rollback of " + std::to_string(undoes.size()) + " edit";
  out += undoes.size() == 1 ? " " : "s ";
  out += std::to_string(undoes.front());
  if (undoes.size() > 1) out += ".." + std::to_string(undoes.back());
  out += " (voxel-cli rollback --undo SEQ brings them back)";
  return out;
}

int world_info(store::WorldStore& s, std::ostream& out) {
  const store::WorldInfo i = s.info();
  out << "world:          " << s.name() << "\n"
      << "seed:           " << i.seed << "\n"
      << "starts:         " << i.starts << "\n"
      << "last sequence:  " << i.last_seq << "\n"
      << "logged edits:   " << i.logged_edits << "\n"
      << "checkpoint:     every edit through " << i.checkpoint_seq << " in " << i.modified_chunks
      << " modified chunks\n"
      << "regions:        " << s.read_regions().regions.size() << " protected\n"
      << "size on disk:   " << i.size_bytes << " bytes\n";
  return 0;
}

int world_log(store::WorldStore& s, uint64_t since, std::ostream& out) {
  std::set<uint64_t> records;
  s.for_each_rollback(0, [&](const store::LoggedEdit& r) { return records.insert(r.seq), true; });
  s.for_each_edit(since, [&](const store::LoggedEdit& e) {
    out << e.seq << "  " << utc_time(e.unix_ms) << "  " << (e.author.empty() ? "-" : e.author)
        << "  "
        << (e.undoes ? describe_rollback(*e.undoes, records) : store::describe_edit(e.edit));
    if (!e.keep.empty())
      out << "  (clipped: " << e.keep.size() << " protected box" << (e.keep.size() == 1 ? "" : "es")
          << " kept)";
    out << "\n";
    return static_cast<bool>(out);
  });
  return 0;
}

// What `world history` lists: the edits of one player, touching a box, in a time span.
struct HistoryFilter {
  std::optional<std::string> player;  // "-" for edits without an author (an open server)
  std::optional<world::VoxelBox> box;
  int64_t since_ms = std::numeric_limits<int64_t>::min();
  int64_t until_ms = std::numeric_limits<int64_t>::max();
  bool matches(const store::LoggedEdit& e) const {
    if (e.undoes) return false;  // the edits, not rollbacks (world log lists those)
    if (e.unix_ms < since_ms || e.unix_ms > until_ms) return false;
    if (player && *player != (e.author.empty() ? "-" : e.author)) return false;
    if (!box) return true;
    const world::VoxelBox t = world::touched_box(e.edit);
    for (int a = 0; a < 3; ++a)
      if (t.hi[a] < box->lo[a] || t.lo[a] > box->hi[a]) return false;
    return true;
  }
};

// The logged edits that match, oldest first, and how far back the log reaches (older
// edits were trimmed by checkpoints: voxeld --history-days, --keep-log).
// With `plan`, also what rolling the listed edits back would change (a dry run of
// store::prepare_rollback: edits rolled back already are not counted again).
int world_history(store::WorldStore& s, const HistoryFilter& filter, bool plan, std::ostream& out) {
  uint64_t first_seq = 0, listed = 0;
  int64_t first_ms = 0;
  std::map<std::string, uint64_t> by_author;
  s.for_each_edit(0, [&](const store::LoggedEdit& e) {
    if (first_seq == 0) first_seq = e.seq, first_ms = e.unix_ms;
    if (!filter.matches(e)) return true;
    ++listed;
    ++by_author[e.author.empty() ? "-" : e.author];
    out << e.seq << "  " << utc_time(e.unix_ms) << "  " << (e.author.empty() ? "-" : e.author)
        << "  " << store::describe_edit(e.edit) << "\n";
    return static_cast<bool>(out);
  });
  out << listed << " edit" << (listed == 1 ? "" : "s");
  for (const auto& [author, n] : by_author)
    out << (author == by_author.begin()->first ? ": " : ", ") << author << " " << n;
  out << "\n";
  if (plan) {
    store::RollbackQuery q{.player = filter.player.value_or(""),
                           .box = filter.box,
                           .since_ms = filter.since_ms,
                           .until_ms = filter.until_ms == std::numeric_limits<int64_t>::max()
                                           ? filter.until_ms
                                           : filter.until_ms + 1};
    const store::WorldInfo info = s.info();
    const store::RollbackOutcome p =
        store::prepare_rollback(s, world::TerrainGenerator(info.seed), q, info.last_seq, true, 0);
    if (!p.refusal.empty())
      out << "rollback plan: refused: " << p.refusal << "\n";
    else
      out << "rollback plan: undoing these " << p.edits << " edits recomputes " << p.chunks.size()
          << " chunks (every other edit in them kept, in its order)\n";
  }
  if (filter.since_ms > std::numeric_limits<int64_t>::min() && first_seq > 1 &&
      filter.since_ms < first_ms)
    out << "warning: --since is before the oldest edit the log holds; the edits before it "
           "were trimmed and are neither listed nor undone\n";
  const store::WorldInfo info = s.info();
  if (first_seq == 0)
    out << "the log holds no edit (" << info.checkpoint_seq
        << " are in the checkpoints: keep history with voxeld --history-days or --keep-log)\n";
  else
    out << "the log reaches back to edit " << first_seq << " (" << utc_time(first_ms) << ")"
        << (first_seq > 1 ? "; older ones were trimmed" : ", the world's first") << "\n";
  return 0;
}

// Replays the log onto a fresh world from the seed and checks every checkpointed chunk
// against it; with a trimmed log, checks that the tail applies onto the checkpoints.
int world_verify(store::WorldStore& s, std::ostream& out, std::ostream& err) {
  const store::WorldInfo info = s.info();
  const world::TerrainGenerator generator(info.seed);
  std::map<world::ChunkCoord, uint64_t> stored;
  s.for_each_chunk([&](world::ChunkCoord c, uint64_t seq) { stored[c] = seq; });
  uint64_t first_logged = 0;
  s.for_each_edit(0, [&](const store::LoggedEdit& e) {
    first_logged = e.seq;
    return false;
  });
  const bool whole_log = info.checkpoint_seq == 0 || (first_logged != 0 && first_logged <= 1);
  world::ChunkMap map;
  size_t mismatches = 0, checked = 0;
  auto check_checkpoints = [&] {
    for (const auto& [c, seq] : stored) {
      const auto record = s.read_chunk(c);
      std::string why;
      const auto chunk = record ? store::decode_chunk(record->samples, &why) : std::nullopt;
      if (!chunk) {
        err << "chunk (" << c.x << ", " << c.y << ", " << c.z << "): " << why << "\n";
        ++mismatches;
        continue;
      }
      if (!map.find(c)) map.insert(c, generator.generate(c));
      if (!(*map.find(c) == *chunk)) {
        err << "chunk (" << c.x << ", " << c.y << ", " << c.z << ") at sequence " << seq
            << " differs from the log replayed onto the seed\n";
        ++mismatches;
      }
      ++checked;
    }
  };
  if (!whole_log) {
    for (const auto& [c, seq] : stored) map.insert(c, store::read_checkpointed_chunk(s, c));
  }
  uint64_t replayed = 0, previous = 0;
  const uint64_t from = whole_log ? 0 : info.checkpoint_seq;
  bool checked_at_checkpoint = !whole_log || info.checkpoint_seq == 0;
  world::EditLimits limits;
  limits.max_radius = limits.max_strength = 1e9f;  // the server's limits may be wider
  auto rollbacks = store::replay_rollbacks_after(s, generator, from);
  s.for_each_edit(from, [&](const store::LoggedEdit& e) {
    if (!checked_at_checkpoint && e.seq > info.checkpoint_seq) {
      check_checkpoints();
      checked_at_checkpoint = true;
    }
    if (e.seq <= previous) throw std::runtime_error("log out of order at " + std::to_string(e.seq));
    previous = e.seq;
    if (e.undoes) {
      for (auto& [c, chunk] : rollbacks.at(e.seq)) map.insert(c, std::move(chunk));
      ++replayed;
      return true;
    }
    if (auto refusal = world::validate(e.edit, limits))
      throw std::runtime_error("logged edit " + std::to_string(e.seq) +
                               " is not valid: " + refusal->message);
    world::replay_edit(map, generator, e.edit, e.keep);
    ++replayed;
    return true;
  });
  if (!checked_at_checkpoint) check_checkpoints();
  out << "verify: " << replayed << " logged edits replayed"
      << (whole_log ? " onto the seed" : " onto the checkpoints") << ", " << checked << " of "
      << stored.size() << " checkpointed chunks checked";
  if (!whole_log) out << " (the log before edit " << first_logged << " was trimmed)";
  out << ": " << (mismatches == 0 ? "all match" : std::to_string(mismatches) + " differ") << "\n";
  return mismatches == 0 ? 0 : 1;
}

}  // namespace

// voxel-cli world backup WORLD --out FILE | restore FILE --to DIR [--force].
int world_backup_restore(const std::vector<std::string>& args, std::ostream& out,
                         std::ostream& err) {
  const bool backup = args[0] == "backup";
  po::options_description opts(backup ? "voxel-cli world backup options"
                                      : "voxel-cli world restore options");
  auto add = opts.add_options();
  add("help,h", "show this help");
  add("from", po::value<std::string>()->required(),
      backup ? "the world directory (voxeld may be running on it)" : "the backup file");
  if (backup) {
    add("out", po::value<std::string>()->required(), "the backup file to write (must not exist)");
  } else {
    add("to", po::value<std::string>()->required(), "the world directory to restore into");
    add("force", po::bool_switch(), "replace the world the directory holds");
  }
  po::positional_options_description positional;
  positional.add("from", 1);
  po::variables_map vm;
  const int rc = parse_options(
      {args.begin() + 1, args.end()}, opts, &positional,
      backup ? "usage: voxel-cli world backup WORLD --out FILE"
             : "usage: voxel-cli world restore FILE --to DIR [--force]   (then verified)",
      vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const std::string from = vm["from"].as<std::string>();
    if (!backup && store::is_postgres_uri(from))
      throw std::invalid_argument("world restore: FILE is a backup file, not a database");
    if (backup && store::is_postgres_uri(from) && store::is_cluster_world(from))
      throw std::invalid_argument(
          "world backup: a cluster's database is backed up with pg_dump (README, \"Backup "
          "and restore\")");
    if (backup) {
      const std::string file = vm["out"].as<std::string>();
      const store::BackupFigures f = store::is_postgres_uri(from)
                                         ? store::backup_postgres_world(from, file)
                                         : store::backup_world(from, file);
      out << "backup: " << file << ", " << f.bytes << " bytes in " << f.seconds
          << " s (restore it with voxel-cli world restore " << file << " --to DIR)\n";
      return 0;
    }
    const std::string dir = vm["to"].as<std::string>();
    const std::string replaced = store::restore_world(from, dir, vm["force"].as<bool>());
    out << "restore: " << from << " -> " << dir << "\n";
    if (!replaced.empty()) out << "the world it held was moved to " << replaced << "\n";
    auto s = store::open_world_store(dir, {.read_only = true});
    world_info(*s, out);
    return world_verify(*s, out, err);
  });
}

int world_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (!args.empty() && args[0] == "migrate")
    return world_migrate({args.begin() + 1, args.end()}, out, err);
  if (!args.empty() && (args[0] == "backup" || args[0] == "restore"))
    return world_backup_restore(args, out, err);
  po::options_description opts("voxel-cli world options");
  opts.add_options()("help,h", "show this help")("action", po::value<std::string>()->required(),
                                                 "info, log, history or verify")(
      "world", po::value<std::string>()->required(), "the world directory, or a postgresql:// URI")(
      "since", po::value<std::string>(),
      "log: edits after this sequence number; history: edits accepted at or after this time "
      "(2026-12-07T10:30:00, UTC) or this long ago (30m, 2h, 7d)")(
      "plan", po::bool_switch(),
      "history: also say what rolling the listed edits back would change (edits undone, "
      "chunks recomputed)");
  add_edit_filter_options(opts, "history");
  po::positional_options_description positional;
  positional.add("action", 1).add("world", 1);
  po::variables_map vm;
  const int rc = parse_options(args, opts, &positional,
                               "usage: voxel-cli world info|log|verify WORLD [--since N]\n       "
                               "voxel-cli world history WORLD [--player ID] [--min X,Y,Z "
                               "--max X,Y,Z] [--since T] [--until T]\n       "
                               "voxel-cli world backup|restore|migrate --help",
                               vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const std::string action = vm["action"].as<std::string>();
    if (action != "info" && action != "log" && action != "verify" && action != "history")
      throw std::invalid_argument("world: the action must be info, log, history or verify");
    HistoryFilter filter;
    uint64_t since_seq = 0;
    if (action == "history") {
      const EditFilter f = parse_edit_filter(vm, "history");
      filter.player = f.player, filter.box = f.box;
      filter.since_ms = f.since_ms, filter.until_ms = f.until_ms;
    } else if (vm.count("since")) {
      const std::string text = vm["since"].as<std::string>();
      const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), since_seq);
      if (ec != std::errc() || end != text.data() + text.size())
        throw std::invalid_argument("--since: a log's sequence number, got '" + text + "'");
    }
    const std::string where = vm["world"].as<std::string>();
    if (action != "log" && action != "history" && store::is_postgres_uri(where) &&
        store::is_cluster_world(where))
      return cluster_world_command(action, where, out, err);
    auto s = store::open_world_store(where, {.read_only = true});
    if (action == "info") return world_info(*s, out);
    if (action == "log") return world_log(*s, since_seq, out);
    if (action == "history") return world_history(*s, filter, vm["plan"].as<bool>(), out);
    return world_verify(*s, out, err);
  });
}

}  // namespace vox::cli
