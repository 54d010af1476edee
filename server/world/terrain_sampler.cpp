#include "server/world/terrain_sampler.hpp"

#include <vector>

namespace vox::world {

void TerrainSampler::sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                                 const std::array<int, 3>& n, Sample* out) const {
  thread_local std::vector<float> lattice;  // a vector: only its three pointers are TLS
  generator_.sample_grid(origin, step, n, out, lattice);
}

}  // namespace vox::world
