// Joins the meshes of a dense grid of chunks into one mesh. Vertices on chunk faces
// (a local coordinate of exactly 0 or 32) are bit-identical to their twins in the
// neighbouring chunk, so each is kept once: by the chunk where it has local coordinate 0
// (the "owner"); the chunk where it sits at 32 points its triangles at the owner's copy.
// Runs in parallel over chunks.
#pragma once

#include <array>
#include <span>

#include "mesh/chunk_mesh.hpp"

namespace vox::mesh {

// parts[i] is the chunk at grid position (i % g.x, i / g.x % g.y, i / g.x / g.y); its
// world origin is origin + 32 * grid position. `threads` 0 uses all cores.
ChunkMesh weld_chunk_grid(std::span<const ChunkMesh> parts, std::array<int, 3> grid, Vec3f origin, int threads = 0);

}  // namespace vox::mesh
