// Joins the meshes of a grid of chunks into one mesh. Vertices on chunk faces (a local
// coordinate of exactly 0 or 32) are bit-identical to their twins in the neighbouring
// chunk, so each world position on a chunk face becomes one vertex: the copy of the first
// chunk that holds and uses it, trying the chunk where it has local coordinate 0 first,
// then the chunks below on those axes; the others point their triangles at that copy. The
// grid may have holes: a chunk that is missing (an empty mesh) holds nothing, so a vertex
// on its face stays with the chunks that have it. Vertices of one chunk at one sample (a
// sample exactly on the iso level) become one vertex too. Vertices no triangle uses are dropped
// (those whose every triangle the mesher dropped as zero-area). Triangles keep their
// order, part by part. Parts must not have a triangle with two vertices at one position
// (the mesher drops zero-area triangles). Runs in parallel over chunks.
#pragma once

#include <array>
#include <span>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::mesh {

// parts[i] is the chunk at grid position (i % g.x, i / g.x % g.y, i / g.x / g.y), an empty
// mesh where there is none; its world origin is origin + 32 * grid position. `threads` 0
// uses all cores.
ChunkMesh weld_chunk_grid(std::span<const ChunkMesh> parts, std::array<int, 3> grid, Vec3f origin,
                          int threads = 0);

}  // namespace vox::mesh
