#include "server/world/terrain_sampler.hpp"

namespace vox::world {

void TerrainSampler::sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                                 const std::array<int, 3>& n, Sample* out) const {
  const ptrdiff_t row = n[0], layer = static_cast<ptrdiff_t>(n[0]) * n[1];
  for (int k = 0; k < n[2]; ++k)
    for (int i = 0; i < n[0]; ++i)
      generator_.sample_column(origin[0] + step * i, origin[2] + step * k, origin[1], step, n[1],
                               out + i + layer * k, row);
}

}  // namespace vox::world
