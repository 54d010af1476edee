// The samples a level-of-detail chunk is meshed from: its own level's samples
// every 2^k voxels, padded like a level-0 chunk's (padded_block.hpp), and on its seams
// (server/world/lod_seams.hpp) the finer level's samples every 2^(k-1) voxels, with one
// more on each side for the normals there. All of them read through a PointSampler, so a
// point holds the same sample in every level that has it.
#pragma once

#include <memory>
#include <vector>

#include "server/mesh/padded_block.hpp"
#include "server/world/lod_layout.hpp"
#include "server/world/point_sampler.hpp"

namespace vox::mesh {

// The seam grid: half-cell points -1..65 on each axis.
inline constexpr int kSeamSide = 2 * world::kChunkSize + 3;
inline constexpr int kSeamVolume = kSeamSide * kSeamSide * kSeamSide;

struct LodBlock {
  LodBlock();
  static constexpr int seam_index(int x, int y, int z) {  // half-cell units, -1..65
    return (x + 1) + kSeamSide * ((y + 1) + kSeamSide * (z + 1));
  }

  world::LodChunk chunk;
  // The seams to mesh. A block gathered for more seams may be meshed with fewer: set this
  // to any subset (normalized) of what it was gathered for.
  world::LodSeams seams;
  PaddedBlock coarse;  // the chunk's own level, block coordinates -1..33
  // The finer level at half-cell points; only the points on split faces and edges and
  // their neighbours hold samples (a point on the coarse lattice holds the coarse sample).
  std::unique_ptr<world::Density[]> seam_density;  // kSeamVolume
  std::unique_ptr<world::Material[]> seam_material;
  std::vector<world::Sample> staging;  // one sampled grid at a time
};

// Fills `out` for chunk `c` with `seams` (normalized here; none at level 0). Reuses out's
// buffers: once warm it allocates nothing. Throws std::invalid_argument for a bad level,
// seams at level 0, or a chunk reaching beyond +-2^30 voxels. The calling thread only.
void gather_lod_block(const world::PointSampler& sampler, const world::LodChunk& c,
                      world::LodSeams seams, LodBlock& out);

}  // namespace vox::mesh
