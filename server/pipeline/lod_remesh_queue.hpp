// Which level-of-detail chunks to re-mesh after edits, and when (issue 16). Pure
// bookkeeping: no I/O, no threads; the clock is passed in.
//
// Rules (each has a unit test in tests/lod_remesh_queue_test.cpp):
// - An edit that changed voxels in a box marks every coarse chunk (levels 1 .. levels-1)
//   whose samples (padded block and seams: voxels [lo - 2^k, lo + 33 * 2^k]) meet the box.
// - Only chunks somebody views are queued (the caller says which); the others have no
//   mesh to update, and are meshed fresh when next viewed (the caller drops their meshes).
// - A chunk is re-meshed at most once per interval: marked again before its interval has
//   passed since it was last taken, it waits until then, and many marks make one re-mesh.
//   So an explosion storm does not re-mesh the horizon every batch, and an edit reaches
//   every level within one interval (plus the re-mesh itself).
// - At most max_pending chunks wait; past that the coarsest are dropped first (whoever
//   views them gets a fresh mesh on the next change or view), and `dropped` counts them.
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

  LodRemeshQueue(int levels, Clock::duration interval, size_t max_pending);

  // The coarse chunks whose samples meet `changed` (voxels, inclusive), for every level
  // 1 .. levels-1, into out (cleared first).
  void affected(const world::VoxelBox& changed, std::vector<world::LodChunk>& out) const;
  // Marks the affected chunks that `viewed` says someone views.
  void mark(const world::VoxelBox& changed, Clock::time_point now,
            const std::function<bool(const world::LodChunk&)>& viewed);
  // Takes up to `max` chunks that are due at `now` (marked, and not taken within the
  // interval), finest level first, and notes them taken at `now`.
  std::vector<world::LodChunk> take_due(Clock::time_point now, size_t max);
  // When the earliest waiting chunk is due; none when nothing waits.
  std::optional<Clock::time_point> next_due() const;
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
  std::set<world::LodChunk> pending_;  // ordered: finest level first
  std::map<world::LodChunk, Clock::time_point> last_taken_;
  uint64_t dropped_ = 0;
};

}  // namespace vox::pipeline
