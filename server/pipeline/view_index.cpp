#include "server/pipeline/view_index.hpp"

#include <algorithm>

namespace vox::pipeline {

using world::ChunkCoord;

ChunkCoord ViewIndex::region_of(ChunkCoord c) {
  return {world::floor_div(c.x, kRegion), world::floor_div(c.y, kRegion),
          world::floor_div(c.z, kRegion)};
}

void ViewIndex::for_regions(const View& v, uint64_t owner, bool add) {
  const ChunkCoord lo = region_of(v.center.offset(-v.radius, -v.radius, -v.radius));
  const ChunkCoord hi = region_of(v.center.offset(v.radius, v.radius, v.radius));
  world::for_each_chunk_in(lo, hi, [&](ChunkCoord region) {
    auto& owners = regions_[region];
    if (add) {
      owners.push_back(owner);
    } else {
      std::erase(owners, owner);
      if (owners.empty()) regions_.erase(region);
    }
  });
}

void ViewIndex::set(uint64_t owner, ChunkCoord center, int radius) {
  if (auto it = views_.find(owner); it != views_.end()) {
    for_regions(it->second, owner, false);
    views_.erase(it);
  }
  if (radius < 0) return;
  const View v{center, radius};
  views_.emplace(owner, v);
  for_regions(v, owner, true);
}

bool ViewIndex::viewed(ChunkCoord c) const {
  auto it = regions_.find(region_of(c));
  if (it == regions_.end()) return false;
  for (uint64_t owner : it->second) {
    const View& v = views_.at(owner);
    const int64_t dx = c.x - v.center.x, dy = c.y - v.center.y, dz = c.z - v.center.z;
    if (dx * dx + dy * dy + dz * dz <= int64_t{v.radius} * v.radius) return true;
  }
  return false;
}

}  // namespace vox::pipeline
