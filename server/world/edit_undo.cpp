#include "server/world/edit_undo.hpp"

#include <algorithm>
#include <unordered_set>

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
ChunkSet dirty_chunks(std::span<const LoggedStep> log, const std::vector<Reach>& reach,
                      size_t max_chunks, size_t& undone, bool& too_many) {
  ChunkSet dirty;
  for (size_t i = 0; i < log.size(); ++i) {
    if (!log[i].undo && !meets(reach[i].reads, dirty)) continue;
    undone += log[i].undo ? 1 : 0;
    dirty.insert(reach[i].writes.begin(), reach[i].writes.end());
    if (max_chunks != 0 && dirty.size() > max_chunks) {
      too_many = true;
      return {};
    }
  }
  return dirty;
}

std::vector<Reach> reaches(std::span<const LoggedStep> log) {
  std::vector<Reach> reach;
  reach.reserve(log.size());
  for (const LoggedStep& s : log) reach.push_back(reach_of(*s.edit));
  return reach;
}

}  // namespace

UndoPlan plan_undo(std::span<const LoggedStep> log, size_t max_chunks) {
  UndoPlan plan;
  const ChunkSet dirty = dirty_chunks(log, reaches(log), max_chunks, plan.undone, plan.too_many);
  plan.chunks.assign(dirty.begin(), dirty.end());
  std::sort(plan.chunks.begin(), plan.chunks.end());
  return plan;
}

UndoResult undo_edits(std::span<const LoggedStep> log, const TerrainGenerator& generator,
                      const std::function<std::optional<Chunk>(ChunkCoord)>& base,
                      size_t max_chunks, int zone_chunks) {
  UndoResult out;
  const std::vector<Reach> reach = reaches(log);
  const ChunkSet dirty = dirty_chunks(log, reach, max_chunks, out.undone, out.too_many);
  if (dirty.empty()) return out;
  // Backward: the edits they depend on, and every chunk those read.
  ChunkSet needed = dirty;
  std::vector<size_t> replay;
  for (size_t i = log.size(); i-- > 0;) {
    if (log[i].undo || !meets(reach[i].writes, needed)) continue;
    replay.push_back(i);
    needed.insert(reach[i].reads.begin(), reach[i].reads.end());
  }
  // From the base, the edits kept, in their order.
  ChunkMap map;
  for (const ChunkCoord& c : needed) {
    std::optional<Chunk> chunk = base(c);
    map.insert(c, chunk ? std::move(*chunk) : generator.generate(c));
  }
  for (auto it = replay.rbegin(); it != replay.rend(); ++it) {
    replay_edit(map, generator, *log[*it].edit, log[*it].keep, zone_chunks);
    ++out.replayed;
  }
  out.chunks.reserve(dirty.size());
  for (const ChunkCoord& c : dirty) out.chunks.emplace_back(c, *map.find(c));
  std::sort(out.chunks.begin(), out.chunks.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

}  // namespace vox::world
