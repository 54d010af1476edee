#include "server/world/edit_undo.hpp"

#include <algorithm>

#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"

namespace vox::world {

namespace {

using ChunkSet = std::unordered_set<ChunkCoord, ChunkCoordHash>;

// The chunks an edit writes, and those it reads (a smooth: around itself; else the same).
struct Reach {
  std::vector<ChunkCoord> writes, reads;
};
Reach reach_of(const Edit& edit) {
  Reach r;
  r.writes = chunks_overlapping(touched_box(edit));
  const auto* smooth = std::get_if<Smooth>(&edit);
  r.reads = smooth ? chunks_overlapping(smooth_read_box(*smooth)) : r.writes;
  return r;
}

bool meets(const std::vector<ChunkCoord>& chunks, const ChunkSet& set) {
  return std::any_of(chunks.begin(), chunks.end(),
                     [&](const ChunkCoord& c) { return set.count(c) != 0; });
}

// Forward: the chunks to recompute.
ChunkSet dirty_chunks(const StepSource& log, size_t max_chunks, size_t& changed, bool& too_many) {
  ChunkSet dirty;
  log(false, [&](const LoggedStep& s) {
    if (too_many || (!s.changed && dirty.empty())) return;
    const Reach r = reach_of(*s.edit);
    if (!s.changed && (s.excluded || !meets(r.reads, dirty))) return;
    changed += s.changed ? 1 : 0;
    dirty.insert(r.writes.begin(), r.writes.end());
    if (max_chunks != 0 && dirty.size() > max_chunks) too_many = true;
  });
  if (too_many) dirty.clear();
  return dirty;
}

}  // namespace

StepSource steps_of(std::span<const LoggedStep> log) {
  return [log](bool newest_first, const std::function<void(const LoggedStep&)>& visit) {
    if (newest_first) {
      for (auto it = log.rbegin(); it != log.rend(); ++it) visit(*it);
    } else {
      for (const LoggedStep& s : log) visit(s);
    }
  };
}

std::unordered_set<uint64_t> excluded_by(std::span<const RollbackMark> records) {
  std::unordered_set<uint64_t> out;
  for (auto it = records.rbegin(); it != records.rend(); ++it)
    if (!out.count(it->seq)) out.insert(it->undoes.begin(), it->undoes.end());
  return out;
}

UndoPlan plan_undo(const StepSource& log, size_t max_chunks) {
  UndoPlan plan;
  const ChunkSet dirty = dirty_chunks(log, max_chunks, plan.changed, plan.too_many);
  plan.chunks.assign(dirty.begin(), dirty.end());
  std::sort(plan.chunks.begin(), plan.chunks.end());
  return plan;
}

UndoResult undo_edits(const StepSource& log, const TerrainGenerator& generator,
                      const std::function<std::optional<Chunk>(ChunkCoord)>& base,
                      size_t max_chunks, int zone_chunks) {
  UndoResult out;
  const ChunkSet dirty = dirty_chunks(log, max_chunks, out.changed, out.too_many);
  if (dirty.empty()) return out;
  // Backward: the edits they depend on, and every chunk those read.
  ChunkSet needed = dirty;
  std::vector<uint64_t> replay;  // newest first
  log(true, [&](const LoggedStep& s) {
    if (out.too_many || s.excluded) return;
    const Reach r = reach_of(*s.edit);
    if (!meets(r.writes, needed)) return;
    replay.push_back(s.seq);
    needed.insert(r.reads.begin(), r.reads.end());
    if (max_chunks != 0 && needed.size() > max_chunks) out.too_many = true;
  });
  if (out.too_many) return out;
  // From the base, the edits kept, in their order.
  ChunkMap map;
  for (const ChunkCoord& c : needed) {
    std::optional<Chunk> chunk = base(c);
    map.insert(c, chunk ? std::move(*chunk) : generator.generate(c));
  }
  auto next = replay.rbegin();
  log(false, [&](const LoggedStep& s) {
    if (next == replay.rend() || s.seq != *next) return;
    replay_edit(map, generator, *s.edit, s.keep, zone_chunks);
    ++out.replayed;
    ++next;
  });
  out.chunks.reserve(dirty.size());
  for (const ChunkCoord& c : dirty) out.chunks.emplace_back(c, *map.find(c));
  std::sort(out.chunks.begin(), out.chunks.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

}  // namespace vox::world
