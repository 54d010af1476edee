// The terrain generator as a PointSampler: a level-of-detail chunk's samples straight from
// the seed (TerrainGenerator::sample_grid).
#pragma once

#include "server/world/point_sampler.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::world {

class TerrainSampler : public PointSampler {
 public:
  explicit TerrainSampler(const TerrainGenerator& generator) : generator_(generator) {}
  void sample_grid(const std::array<int32_t, 3>& origin, int32_t step, const std::array<int, 3>& n,
                   Sample* out) const override;

 private:
  const TerrainGenerator& generator_;
};

}  // namespace vox::world
