// The mesher's input: a chunk's samples plus one sample before and two after it on every
// axis (block coordinates -1..33), gathered from the 26 neighbours. Cells 0..31 need
// samples 0..32; central-difference normals at those samples need -1..33.
#pragma once

#include <array>
#include <span>

#include "server/world/chunk.hpp"
#include "server/world/chunk_map.hpp"

namespace vox::mesh {

inline constexpr int kBlockSide = world::kChunkSize + 3;
inline constexpr int kBlockVolume = kBlockSide * kBlockSide * kBlockSide;

struct PaddedBlock {
  PaddedBlock();
  static constexpr int index(int x, int y, int z) {  // x, y, z in -1..33
    return (x + 1) + kBlockSide * ((y + 1) + kBlockSide * (z + 1));
  }
  // Cells to mesh along x, y, z (1..32): cells [0, n) read samples [0, n]. A whole chunk
  // meshes 32; the last chunk of an offline volume may mesh fewer.
  std::array<int, 3> cells{world::kChunkSize, world::kChunkSize, world::kChunkSize};
  // Solid is density > 0 (the world's rule), or >= 0 when set: offline volumes, where a
  // sample exactly on the iso level counts as inside, as VTK's Flying Edges counts it.
  bool zero_is_solid = false;
  // A sample is solid when its density is above this.
  world::Density solid_floor() const {
    return zero_is_solid ? world::Density{-1} : world::Density{0};
  }
  std::unique_ptr<world::Density[]> density;  // kBlockVolume
  std::unique_ptr<world::Material[]> material;
};

// neighbours[(dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)] is the chunk at offset (dx, dy, dz);
// a null entry reads as air.
void gather_padded_block(std::span<const world::Chunk* const, 27> neighbours, PaddedBlock& out);
// Missing chunks read as air.
void gather_padded_block(const world::ChunkMap& map, world::ChunkCoord c, PaddedBlock& out);

}  // namespace vox::mesh
