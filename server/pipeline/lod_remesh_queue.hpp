// Which level-of-detail chunks to re-mesh after edits, and when. Pure
// bookkeeping: no I/O, no threads; the clock is passed in.
//
// Rules (each has a unit test in tests/lod_remesh_queue_test.cpp):
// - An edit that changed voxels in a box marks every coarse chunk (levels 1 .. levels-1)
//   whose samples (padded block and seams: voxels [lo - 2^k, lo + 33 * 2^k]) meet the box.
// - Only chunks somebody views are queued (the caller says which); the others have no
//   mesh to update, and are meshed fresh when next viewed (the caller drops their meshes).
// - A chunk is re-meshed at most once per its level's interval: `interval` at level 1,
//   doubling with each coarser level up to kMaxIntervalFactor times it. Marked again
//   before that has passed since it was last taken, it waits until then, and many marks
//   make one re-mesh. A chunk not taken within its interval is due at once. So an
//   explosion storm does not re-mesh the horizon every batch (a coarse chunk covers many
//   players' edits, and each re-mesh goes to every viewer of it), and an edit reaches
//   level k within its interval (plus the re-mesh itself). Due chunks are taken in the
//   order they fell due (finest first between equals), so no level starves another.
// - At most max_pending chunks wait; past that the coarsest are dropped first (whoever
//   views them gets a fresh mesh: the caller drops their meshes, take_dropped()), and
//   `dropped` counts them.
//
// One thread at a time (the pipeline thread).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "server/world/edit.hpp"
#include "server/world/lod_layout.hpp"

namespace vox::pipeline {

class LodRemeshQueue {
 public:
  using Clock = std::chrono::steady_clock;

  static constexpr int kMaxIntervalFactor = 8;

  // `interval`: level 1's.
  LodRemeshQueue(int levels, Clock::duration interval, size_t max_pending);
  // How often a chunk of `level` (1 ..) may be re-meshed.
  Clock::duration interval(int level) const;

  // The coarse chunks whose samples meet `changed` (voxels, inclusive), for every level
  // 1 .. levels-1, into out (cleared first).
  void affected(const world::VoxelBox& changed, std::vector<world::LodChunk>& out) const;
  // Marks the affected chunks that `viewed` says someone views.
  void mark(const world::VoxelBox& changed, Clock::time_point now,
            const std::function<bool(const world::LodChunk&)>& viewed);
  // Takes up to `max` chunks that are due at `now` (marked, and not taken within the
  // interval), the earliest due first (finest first between equals), and notes them taken
  // at `now`.
  std::vector<world::LodChunk> take_due(Clock::time_point now, size_t max);
  // When the earliest waiting chunk is due; none when nothing waits. O(1).
  std::optional<Clock::time_point> next_due() const;
  // The chunks dropped since the last call (past max_pending): their meshes are stale.
  std::vector<world::LodChunk> take_dropped();
  // Forgets a chunk nobody views any more (pending or not).
  void forget(const world::LodChunk& c);

  size_t pending() const { return pending_.size(); }
  uint64_t dropped() const { return dropped_; }

 private:
  Clock::time_point due_time(const world::LodChunk& c) const;
  void forget_old_takes(Clock::time_point now);

  int levels_;
  Clock::duration interval_;
  size_t max_pending_;
  std::map<world::LodChunk, Clock::time_point> pending_;            // -> due; ordered: finest first
  std::set<std::pair<Clock::time_point, world::LodChunk>> by_due_;  // the same, by due time
  std::vector<world::LodChunk> dropped_chunks_;
  std::map<world::LodChunk, Clock::time_point> last_taken_;
  uint64_t dropped_ = 0;
};

}  // namespace vox::pipeline
