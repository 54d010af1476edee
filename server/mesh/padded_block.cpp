#include "server/mesh/padded_block.hpp"

#include <cstring>

namespace vox::mesh {
namespace {

using world::Chunk;
using world::kChunkSize;

// Block coordinate b in -1..33 comes from neighbour 0 (b = -1, its sample 31), 1 (the
// centre chunk, b = 0..31) or 2 (b = 32, 33: its samples 0, 1).
constexpr int source_of(int b) { return b < 0 ? 0 : (b < kChunkSize ? 1 : 2); }
constexpr int local_of(int b) {
  return b < 0 ? kChunkSize - 1 : (b < kChunkSize ? b : b - kChunkSize);
}

// Copies `count` samples of one x-row of `src` starting at local (x, y, z), or fills them
// with the uniform sample (air when src is null).
inline void copy_row(const Chunk* src, int x, int y, int z, int count, world::Density* dst_d,
                     world::Material* dst_m) {
  if (src == nullptr || src->is_uniform()) {
    const world::Sample s = src == nullptr ? world::Sample{} : src->uniform_value();
    for (int i = 0; i < count; ++i) dst_d[i] = s.density;
    for (int i = 0; i < count; ++i) dst_m[i] = s.material;
    return;
  }
  const int from = Chunk::index(x, y, z);
  std::memcpy(dst_d, src->densities() + from, count * sizeof(world::Density));
  std::memcpy(dst_m, src->materials() + from, count * sizeof(world::Material));
}

}  // namespace

PaddedBlock::PaddedBlock()
    : density(std::make_unique<world::Density[]>(kBlockVolume)),
      material(std::make_unique<world::Material[]>(kBlockVolume)) {}

void gather_padded_block(std::span<const Chunk* const, 27> neighbours, PaddedBlock& out) {
  out.cells = {kChunkSize, kChunkSize, kChunkSize};
  for (int bz = -1; bz <= kChunkSize + 1; ++bz) {
    for (int by = -1; by <= kChunkSize + 1; ++by) {
      const int row = 3 * source_of(by) + 9 * source_of(bz), ly = local_of(by), lz = local_of(bz);
      const int dst = PaddedBlock::index(-1, by, bz);
      world::Density* d = out.density.get() + dst;
      world::Material* m = out.material.get() + dst;
      copy_row(neighbours[row + 0], kChunkSize - 1, ly, lz, 1, d, m);
      copy_row(neighbours[row + 1], 0, ly, lz, kChunkSize, d + 1, m + 1);
      copy_row(neighbours[row + 2], 0, ly, lz, 2, d + 1 + kChunkSize, m + 1 + kChunkSize);
    }
  }
}

void gather_padded_block(const world::ChunkMap& map, world::ChunkCoord c, PaddedBlock& out) {
  std::array<const Chunk*, 27> neighbours{};
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        neighbours[(dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)] = map.find(c.offset(dx, dy, dz));
  gather_padded_block(neighbours, out);
}

}  // namespace vox::mesh
