// Samples of the world at any grid of points: what a level-of-detail chunk is meshed from
// (a level-k chunk reads the world every 2^k voxels, and the finer level's points on its
// seams). Implementations: the terrain generator with the modified chunks laid over it
// (the server), an analytic field (tests).
#pragma once

#include <array>
#include <cstdint>

#include "server/world/sample.hpp"

namespace vox::world {

class PointSampler {
 public:
  virtual ~PointSampler() = default;
  // Writes the samples at origin + step * (i, j, k), voxel coordinates, for i < n[0],
  // j < n[1], k < n[2], to out[i + n[0] * (j + n[1] * k)]. The same point gives the same
  // sample whatever grid it is part of. Any thread, concurrently.
  virtual void sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                           const std::array<int, 3>& n, Sample* out) const = 0;
};

}  // namespace vox::world
