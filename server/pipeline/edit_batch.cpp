#include "server/pipeline/edit_batch.hpp"

#include <algorithm>

namespace vox::pipeline {

void Undo::save(world::ChunkCoord c, const world::Chunk& chunk, const world::VoxelBox& box,
                bool modified, bool unsaved) {
  Patch& p = patches.emplace_back();
  p.coord = c;
  p.modified = modified;
  p.unsaved = unsaved;
  p.was_uniform = chunk.is_uniform();
  if (p.was_uniform) {
    p.uniform = chunk.uniform_value();
    return;
  }
  const int32_t o[3] = {c.x * world::kChunkSize, c.y * world::kChunkSize, c.z * world::kChunkSize};
  for (int a = 0; a < 3; ++a) {  // an edit writes only within its box (world/edit_apply)
    p.lo[a] = std::max(0, box.lo[a] - o[a]);
    p.hi[a] = std::min(world::kChunkSize - 1, box.hi[a] - o[a]);
  }
  for (int z = p.lo[2]; z <= p.hi[2]; ++z)
    for (int y = p.lo[1]; y <= p.hi[1]; ++y)
      for (int x = p.lo[0]; x <= p.hi[0]; ++x) p.samples.push_back(chunk.at(x, y, z));
}

}  // namespace vox::pipeline
