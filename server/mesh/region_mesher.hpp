// Meshes every chunk of a box of loaded chunks in parallel (one padded block and scratch
// per worker thread) and welds the result into one world-space mesh.
#pragma once

#include <vector>

#include "server/mesh/chunk_mesh.hpp"
#include "server/world/chunk_map.hpp"

namespace vox::mesh {

struct ChunkBox {
  world::ChunkCoord lo, hi;  // inclusive
  size_t count() const {
    return static_cast<size_t>(hi.x - lo.x + 1) * (hi.y - lo.y + 1) * (hi.z - lo.z + 1);
  }
  world::ChunkCoord at(size_t i) const;  // x fastest
};

// One mesh per chunk of the box, chunk-local positions, in ChunkBox::at order. Chunks
// missing from the map read as air.
std::vector<ChunkMesh> mesh_chunks(const world::ChunkMap& map, const ChunkBox& box,
                                   int threads = 0);
// The same chunks welded into one mesh in world coordinates.
ChunkMesh mesh_region(const world::ChunkMap& map, const ChunkBox& box, int threads = 0);

}  // namespace vox::mesh
