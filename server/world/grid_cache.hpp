// Generated terrain grids kept for reuse: a coarse chunk is re-meshed after each
// edit near it, and a layout change meshes it again with other seams; both read the same
// generator grids (only the modified chunks laid over them differ). Bounded in bytes, the
// least recently used grid dropped first. A grid is kept as runs of equal samples in its
// own order, 4 bytes a run of up to 256: terrain is mostly sky and rock, so a coarse
// chunk's 35^3 samples take a tenth to a fifth of their size, and the bound keeps ten times as many
// grids (a crowd's first views mesh each chunk once per seams variant, a player at a time). Any
// thread: one leaf mutex, held to look up or insert (grids are shared immutable vectors, copied
// outside it).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "server/world/sample.hpp"

namespace vox::world {

class GridCache {
 public:
  struct Key {
    std::array<int32_t, 3> origin;
    int32_t step;
    std::array<int, 3> n;
    friend bool operator==(const Key&, const Key&) = default;
  };

  struct Run {  // `more` + 1 samples in a row (the grid's order) equal to this one
    Density density;
    Material material;
    uint8_t more;
  };

  explicit GridCache(size_t max_bytes) : max_bytes_(max_bytes) {}

  // Writes the grid to `out` (n[0] * n[1] * n[2] samples); false when it is not kept.
  bool get(const Key& k, Sample* out);
  void put(const Key& k, const Sample* samples);
  size_t bytes() const { return bytes_.load(std::memory_order_relaxed); }

 private:
  struct KeyHash {
    size_t operator()(const Key& k) const;
  };
  using Grid = std::shared_ptr<const std::vector<Run>>;
  using Order = std::list<Key>;  // most recently used first
  struct Entry {
    Grid grid;
    Order::iterator at;
  };

  const size_t max_bytes_;
  std::mutex mutex_;  // leaf lock
  std::unordered_map<Key, Entry, KeyHash> grids_;
  Order order_;
  std::atomic<size_t> bytes_{0};
};

}  // namespace vox::world
