// The live views (one ball of chunks per owner), indexed by 16-chunk regions, so that
// eviction can ask "is this chunk in someone's view?" cheaply. Pure; pipeline thread only
// (the pipeline copies view changes in at each batch).
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "server/world/chunk_coord.hpp"

namespace vox::pipeline {

class ViewIndex {
 public:
  static constexpr int kRegion = 16;  // chunks per region side

  // Sets (or moves) the owner's view; radius < 0 removes it.
  void set(uint64_t owner, world::ChunkCoord center, int radius);
  void remove(uint64_t owner) { set(owner, {}, -1); }
  bool viewed(world::ChunkCoord c) const;
  size_t size() const { return views_.size(); }

 private:
  struct View {
    world::ChunkCoord center;
    int radius = -1;
  };
  struct RegionHash {
    size_t operator()(const world::ChunkCoord& c) const { return world::ChunkCoordHash{}(c); }
  };
  static world::ChunkCoord region_of(world::ChunkCoord c);
  void for_regions(const View& v, uint64_t owner, bool add);

  std::unordered_map<uint64_t, View> views_;
  std::unordered_map<world::ChunkCoord, std::vector<uint64_t>, RegionHash> regions_;
};

}  // namespace vox::pipeline
