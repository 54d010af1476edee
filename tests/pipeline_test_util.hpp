// What the pipeline's store tests share: the samples of a cube around a point, read by an
// inspection (so they include every edit queued before it), and polling for a condition
// (tests/eventually.hpp).
#pragma once

#include <chrono>
#include <thread>
#include <vector>

#include "server/pipeline/world_pipeline.hpp"
#include "tests/eventually.hpp"

namespace vox::test {

inline std::vector<world::Sample> samples_around(pipeline::WorldPipeline& p, int x0, int y0, int z0,
                                                 int r) {
  std::vector<world::Sample> out;
  p.inspect([&](const world::ChunkMap& map) {
    for (int z = z0 - r; z <= z0 + r; ++z)
      for (int y = y0 - r; y <= y0 + r; ++y)
        for (int x = x0 - r; x <= x0 + r; ++x) out.push_back(map.sample_at(x, y, z));
  });
  return out;
}

}  // namespace vox::test
