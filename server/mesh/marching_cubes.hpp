// Marching cubes over one padded chunk block. One entry point, caller-owned scratch,
// caller-reused output: once the buffers are big enough nothing is allocated.
#pragma once

#include <array>
#include <cstdint>

#include "mesh/chunk_mesh.hpp"
#include "mesh/padded_block.hpp"

namespace vox::mesh {

inline constexpr int kRowsPerAxis = world::kChunkSize + 1;
inline constexpr int kRows = kRowsPerAxis * kRowsPerAxis;

// Per (y, z) row of samples: bit x set when sample (x, y, z) is solid; per axis, the cut
// edges starting at each sample and the index of the row's first vertex on that axis.
struct MeshScratch {
  std::array<uint64_t, kRows> solid;
  std::array<std::array<uint64_t, kRows>, 3> cut;
  std::array<std::array<uint32_t, kRows>, 3> first_vertex;
};

// Meshes cells [0, in.cells) of the block into `out` (cleared first). Vertices on the
// block's faces depend only on the samples of that face, so neighbouring chunks produce
// bit-identical vertices there (in world space).
void mesh_chunk(const PaddedBlock& in, MeshScratch& scratch, ChunkMesh& out);

}  // namespace vox::mesh
