#include "server/store/world_history.hpp"

#include <algorithm>
#include <unordered_set>

#include "server/store/edit_codec.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"
#include "server/world/edit_undo.hpp"
#include "server/world/region.hpp"

namespace vox::store {

namespace {

using world::ChunkCoord;

std::string at_text(uint64_t seq, int64_t ms) {
  return "edit " + std::to_string(seq) + ", accepted at unix ms " + std::to_string(ms);
}

std::optional<world::Chunk> base_chunk(WorldStore& s, ChunkCoord c) {
  const std::optional<ChunkRecord> r = s.read_base_chunk(c);
  if (!r) return std::nullopt;
  std::string why;
  std::optional<world::Chunk> chunk = decode_chunk(r->samples, &why);
  if (!chunk)
    throw StoreError(s.name() + ": the history's base chunk (" + std::to_string(c.x) + ", " +
                     std::to_string(c.y) + ", " + std::to_string(c.z) + "): " + why);
  return chunk;
}

std::vector<world::RollbackMark> marks_of(const std::vector<LoggedEdit>& records) {
  std::vector<world::RollbackMark> marks;
  marks.reserve(records.size() + 1);
  for (const LoggedEdit& r : records) marks.push_back({r.seq, *r.undoes});
  return marks;
}

// The log's edits in (base, through], as undo steps: left out of the result when `after`
// excludes them, changed when `now` and `after` disagree.
world::StepSource steps(WorldStore& s, uint64_t base, uint64_t through,
                        const std::unordered_set<uint64_t>& now,
                        const std::unordered_set<uint64_t>& after) {
  return [&s, base, through, &now, &after](
             bool newest_first, const std::function<void(const world::LoggedStep&)>& visit) {
    const auto each = [&](const LoggedEdit& e) {
      if (e.seq > through) return false;
      if (e.undoes) return true;
      const bool out = after.count(e.seq) != 0;
      visit({e.seq, &e.edit, e.keep, out, out != (now.count(e.seq) != 0)});
      return true;
    };
    newest_first ? s.for_each_edit_back(base, through, each) : s.for_each_edit(base, each);
  };
}

// Recomputes (or plans) the world of `records` + `next` against that of `records` alone.
RollbackOutcome recompute(WorldStore& s, const world::TerrainGenerator& generator, uint64_t base,
                          const std::vector<LoggedEdit>& records, const std::vector<uint64_t>& next,
                          uint64_t through, bool dry_run, size_t max_chunks, int zone_chunks) {
  RollbackOutcome out;
  out.undoes = next;
  std::vector<world::RollbackMark> marks = marks_of(records);
  const std::unordered_set<uint64_t> now = world::excluded_by(marks);
  marks.push_back({std::numeric_limits<uint64_t>::max(), next});
  const std::unordered_set<uint64_t> after = world::excluded_by(marks);
  const world::StepSource log = steps(s, base, through, now, after);
  if (dry_run) {
    world::UndoPlan p = world::plan_undo(log, max_chunks);
    out.edits = p.changed, out.too_many = p.too_many, out.chunks = std::move(p.chunks);
    return out;
  }
  world::UndoResult r = world::undo_edits(
      log, generator, [&s](ChunkCoord c) { return base_chunk(s, c); }, max_chunks, zone_chunks);
  out.edits = r.changed, out.too_many = r.too_many;
  for (const auto& [c, chunk] : r.chunks) out.chunks.push_back(c);
  out.recomputed = std::move(r.chunks);
  return out;
}

std::vector<LoggedEdit> records_through(WorldStore& s, uint64_t base, uint64_t through) {
  std::vector<LoggedEdit> records;
  s.for_each_rollback(base, [&](const LoggedEdit& r) {
    if (r.seq > through) return false;
    records.push_back(r);
    return true;
  });
  return records;
}

}  // namespace

RollbackOutcome prepare_rollback(WorldStore& s, const world::TerrainGenerator& generator,
                                 const RollbackQuery& q, uint64_t through, bool dry_run,
                                 size_t max_chunks, int zone_chunks) {
  RollbackOutcome out;
  const WorldInfo info = s.info();
  if (!info.base_seq) {
    out.refusal =
        "this world keeps no history to roll back yet: voxeld --history-days 0 trims the log "
        "whole, and a world from before rollbacks starts its history at its next checkpoint";
    return out;
  }
  const uint64_t base = *info.base_seq;
  const std::vector<LoggedEdit> records = records_through(s, base, through);
  const std::unordered_set<uint64_t> now = world::excluded_by(marks_of(records));
  std::vector<uint64_t> targets;
  bool first = true;
  s.for_each_edit(base, [&](const LoggedEdit& e) {
    if (e.seq > through) return false;
    if (first) out.history_from = e.seq, out.history_from_ms = e.unix_ms, first = false;
    if (q.undo_record != 0 || e.undoes || now.count(e.seq)) return true;
    if (!q.player.empty() && e.author != (q.player == "-" ? "" : q.player)) return true;
    if (e.unix_ms < q.since_ms || e.unix_ms >= q.until_ms) return true;
    if (q.box && !world::boxes_intersect(*q.box, world::touched_box(e.edit))) return true;
    targets.push_back(e.seq);
    return true;
  });
  if (q.undo_record != 0) {
    const auto it = std::find_if(records.begin(), records.end(),
                                 [&](const LoggedEdit& r) { return r.seq == q.undo_record; });
    if (it == records.end()) {
      out.refusal =
          "no rollback " + std::to_string(q.undo_record) + " in the history (" +
          (out.history_from ? "it reaches back to " + at_text(out.history_from, out.history_from_ms)
                            : std::string("it is empty")) +
          ")";
    } else if (now.count(it->seq)) {
      out.refusal = "rollback " + std::to_string(it->seq) + " is undone already";
    } else if (it->undoes->front() <= base) {
      out.refusal = "rollback " + std::to_string(it->seq) +
                    " undid edits older than the history holds: they cannot come back";
    } else {
      targets.push_back(it->seq);
    }
    if (!out.refusal.empty()) return out;
  } else if (q.since_ms != std::numeric_limits<int64_t>::min() && base > 0 &&
             (out.history_from == 0 || q.since_ms < out.history_from_ms)) {
    out.refusal = "the history reaches back only to " +
                  (out.history_from ? at_text(out.history_from, out.history_from_ms)
                                    : "edit " + std::to_string(base + 1)) +
                  " (voxeld --history-days); --since is before it";
    return out;
  }
  if (targets.empty()) return out;
  if (targets.size() > kMaxRollbackSeqs) {
    out.refusal = "it would undo " + std::to_string(targets.size()) + " edits, more than " +
                  std::to_string(kMaxRollbackSeqs) + " at once: narrow it (a box, a time)";
    return out;
  }
  RollbackOutcome r =
      recompute(s, generator, base, records, targets, through, dry_run, max_chunks, zone_chunks);
  r.history_from = out.history_from, r.history_from_ms = out.history_from_ms;
  return r;
}

std::vector<std::pair<ChunkCoord, world::Chunk>> replay_rollback(
    WorldStore& s, const world::TerrainGenerator& generator, const LoggedEdit& record,
    int zone_chunks) {
  const WorldInfo info = s.info();
  if (!info.base_seq)
    throw StoreError(s.name() + ": rollback " + std::to_string(record.seq) +
                     " is logged but the world keeps no history's base");
  const std::vector<LoggedEdit> records = records_through(s, *info.base_seq, record.seq - 1);
  RollbackOutcome r = recompute(s, generator, *info.base_seq, records, *record.undoes,
                                record.seq - 1, false, 0, zone_chunks);
  return std::move(r.recomputed);
}

std::map<uint64_t, std::vector<std::pair<ChunkCoord, world::Chunk>>> replay_rollbacks_after(
    WorldStore& s, const world::TerrainGenerator& generator, uint64_t after_seq) {
  std::vector<LoggedEdit> records;
  s.for_each_rollback(after_seq, [&](const LoggedEdit& r) {
    records.push_back(r);
    return true;
  });
  std::map<uint64_t, std::vector<std::pair<ChunkCoord, world::Chunk>>> out;
  for (const LoggedEdit& r : records) out[r.seq] = replay_rollback(s, generator, r);
  return out;
}

HistoryStep advance_history(WorldStore& s, const world::TerrainGenerator& generator,
                            const LogTrim& window, uint64_t checkpoint_seq, ChunkEncoder& encoder) {
  // Bounds per call: the edits held and the chunks held (about 100 KB each).
  constexpr size_t kMaxEdits = 100'000, kMaxChunks = 256;
  HistoryStep step;
  const WorldInfo info = s.info();
  const bool keeps_all = window.through == 0 || !window.windowed();
  // A world without a base: the checkpoint becomes it, but not where the log is kept
  // whole (an audit trail is never trimmed; such a world gets no history).
  if (!info.base_seq && keeps_all) return step;
  if (!info.base_seq) {
    s.reset_base();
    step.reset = true;
    step.through = info.checkpoint_seq;
    return step;
  }
  if (keeps_all) return step;
  const uint64_t base = *info.base_seq;
  const std::vector<LoggedEdit> records = records_through(s, base, info.last_seq);
  const std::unordered_set<uint64_t> out = world::excluded_by(marks_of(records));
  // A record past the checkpoint is replayed by a restart from it: the base stays before
  // every edit such a record reaches (through the records it undoes too), or the replay
  // would not see that edit change.
  uint64_t floor = std::numeric_limits<uint64_t>::max();
  {
    std::unordered_set<uint64_t> reached;
    std::vector<uint64_t> todo;
    for (const LoggedEdit& r : records)
      if (r.seq > checkpoint_seq) todo.push_back(r.seq);
    while (!todo.empty()) {
      const uint64_t seq = todo.back();
      todo.pop_back();
      const auto it = std::find_if(records.begin(), records.end(),
                                   [&](const LoggedEdit& r) { return r.seq == seq; });
      if (it == records.end()) continue;
      for (const uint64_t u : *it->undoes) {
        floor = std::min(floor, u);
        if (reached.insert(u).second) todo.push_back(u);
      }
    }
  }
  std::vector<LoggedEdit> leaving;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> reach;
  uint64_t through = base;
  s.for_each_edit(base, [&](const LoggedEdit& e) {
    if (e.seq > std::min(checkpoint_seq, window.through) || e.seq >= floor) return false;
    if (e.undoes) {
      through = e.seq;
      return true;
    }
    if (e.unix_ms >= window.accepted_before_ms && e.unix_ms <= window.stamps_until_ms)
      return false;  // the first edit the window keeps
    if (!out.count(e.seq)) {
      const auto* smooth = std::get_if<world::Smooth>(&e.edit);
      const world::VoxelBox box =
          smooth ? world::smooth_read_box(*smooth) : world::touched_box(e.edit);
      const std::vector<ChunkCoord> cs = world::chunks_overlapping(box);
      size_t adds = 0;
      for (const ChunkCoord& c : cs) adds += reach.count(c) ? 0 : 1;
      if (!leaving.empty() && reach.size() + adds > kMaxChunks) return false;
      reach.insert(cs.begin(), cs.end());
      leaving.push_back(e);
    }
    through = e.seq;
    return leaving.size() < kMaxEdits;
  });
  if (through == base) return step;
  world::ChunkMap map;
  for (const ChunkCoord& c : reach) {
    std::optional<world::Chunk> chunk = base_chunk(s, c);
    map.insert(c, chunk ? std::move(*chunk) : generator.generate(c));
  }
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> changed;
  for (const LoggedEdit& e : leaving)
    for (const ChunkCoord& c : world::replay_edit(map, generator, e.edit, e.keep))
      changed.insert(c);
  std::vector<ChunkRecord> rows;
  rows.reserve(changed.size());
  for (const ChunkCoord& c : changed) rows.push_back({c, through, encoder.encode(*map.find(c))});
  s.advance_base(rows, through);
  step.through = through, step.edits = leaving.size(), step.chunks = rows.size();
  return step;
}

}  // namespace vox::store
