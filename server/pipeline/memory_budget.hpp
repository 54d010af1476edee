// When the world pipeline evicts and how much it may load, given the bytes it accounts
// (chunks, meshes, and what sessions report). Pure: no I/O, no threads; unit-tested in
// tests/batch_scheduler_test.cpp.
//
// - Above 90 % of the budget, unused unmodified chunks and meshes are evicted (least
//   recently used first) down to 80 %.
// - Loads go on only below the budget, and a load pass is cut so that its worst case
//   (every chunk generated non-uniform, plus its mesh) keeps the total under 110 %.
#pragma once

#include <cstddef>

namespace vox::pipeline {

class MemoryBudget {
 public:
  // Worst-case bytes one unit of load work adds (a generated chunk is 4 units: 96 KiB of
  // samples plus a mesh and its encodings).
  static constexpr size_t kBytesPerLoadWork = 40 * 1024;

  explicit MemoryBudget(size_t max_bytes = 0) : max_(max_bytes) {}  // 0: no budget
  size_t max_bytes() const { return max_; }
  bool limited() const { return max_ != 0; }

  bool should_evict(size_t total) const { return max_ != 0 && total > max_ / 10 * 9; }
  // What the evictable part (chunks and meshes) may take after eviction when `other`
  // bytes (sessions' state, modified chunks) cannot be evicted.
  size_t evict_target(size_t other) const {
    const size_t low = max_ / 10 * 8;
    return other >= low ? 0 : low - other;
  }
  // Load work allowed in the next pass (at most `full`): none at or over the budget.
  size_t load_work(size_t total, size_t full) const {
    if (max_ == 0) return full;
    if (total >= max_) return 0;
    const size_t headroom = (max_ + max_ / 10 - total) / kBytesPerLoadWork;
    return headroom < full ? headroom : full;
  }
  // Bytes a mesh still to be made is counted at (a rough surface chunk's mesh, encoding
  // and full frame together; most take less).
  static constexpr size_t kBytesPerMesh = 96 * 1024;
  // Worst-case bytes of a chunk an edit generates (samples of a non-uniform chunk).
  static constexpr size_t kBytesPerChunk = 96 * 1024 + 64;
  // An edit may generate the `chunks` it needs only below the budget, and only when their
  // worst case stays under 110 %.
  bool may_generate(size_t total, size_t chunks) const {
    return max_ == 0 || (total < max_ && total + chunks * kBytesPerChunk <= max_ + max_ / 10);
  }

 private:
  size_t max_;
};

}  // namespace vox::pipeline
