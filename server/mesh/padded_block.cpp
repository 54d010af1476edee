#include "mesh/padded_block.hpp"

#include <algorithm>
#include <cstring>

namespace vox::mesh {
namespace {

using world::Chunk;
using world::kChunkSize;

// Block coordinate b in -1..33 splits into three source ranges: [-1] from the chunk
// before (its sample 31), [0, 31] from the centre chunk, [32, 33] from the chunk after.
struct Span {
  int first_block, count, offset, first_local;
};
constexpr Span kSpans[3] = {{-1, 1, 0, kChunkSize - 1}, {0, kChunkSize, 1, 0}, {kChunkSize, 2, 2, 0}};

}  // namespace

PaddedBlock::PaddedBlock()
    : density(std::make_unique<world::Density[]>(kBlockVolume)),
      material(std::make_unique<world::Material[]>(kBlockVolume)) {}

void gather_padded_block(std::span<const Chunk* const, 27> neighbours, PaddedBlock& out) {
  out.cells = {kChunkSize, kChunkSize, kChunkSize};
  for (const Span& sz : kSpans) {
    for (const Span& sy : kSpans) {
      for (const Span& sx : kSpans) {
        const Chunk* src = neighbours[sx.offset + 3 * sy.offset + 9 * sz.offset];
        for (int k = 0; k < sz.count; ++k) {
          for (int j = 0; j < sy.count; ++j) {
            const int dst = PaddedBlock::index(sx.first_block, sy.first_block + j, sz.first_block + k);
            if (src == nullptr || src->is_uniform()) {
              const world::Sample s = src == nullptr ? world::Sample{} : src->uniform_value();
              std::fill_n(out.density.get() + dst, sx.count, s.density);
              std::fill_n(out.material.get() + dst, sx.count, s.material);
            } else {
              const int from = Chunk::index(sx.first_local, sy.first_local + j, sz.first_local + k);
              std::memcpy(out.density.get() + dst, src->densities() + from,
                          sx.count * sizeof(world::Density));
              std::memcpy(out.material.get() + dst, src->materials() + from,
                          sx.count * sizeof(world::Material));
            }
          }
        }
      }
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
