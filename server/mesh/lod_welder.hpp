// Joins the meshes of a level-of-detail view (chunks of several levels) into one
// mesh in world positions. A vertex on a seam is bit-identical to its twin in the chunk
// across (docs/PROTOCOL.md §2.7), so vertices are joined by exact world position; vertices
// no triangle uses are dropped. Parts are taken level by level in coordinate order,
// whatever order they come in, so the same view welds to the same mesh every time.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::mesh {

struct LodPart {
  uint32_t level = 0;
  std::array<int32_t, 3> chunk{};   // in chunks of its level (side 32 * 2^level voxels)
  const ChunkMesh* mesh = nullptr;  // chunk-local positions in the level's cells
};

// Any thread; the meshes must outlive the call.
ChunkMesh weld_lod_parts(std::vector<LodPart> parts);

}  // namespace vox::mesh
