// What the store's tests share: one edit of every kind (and both stamp shapes), with
// floats that are not round numbers, so an inexact round trip shows; a chunk of random
// samples.
#pragma once

#include <random>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/edit.hpp"

namespace vox::test {

// A chunk of pseudo-random samples (no two seeds alike): one that compresses badly.
inline world::Chunk full_chunk(uint32_t seed) {
  world::Chunk c;
  std::mt19937 rng(seed);
  for (int i = 0; i < world::kChunkVolume; ++i) {
    c.densities()[i] = static_cast<world::Density>(static_cast<int>(rng() % 65535) - 32767);
    c.materials()[i] = static_cast<world::Material>(rng() % 4);
  }
  return c;
}

inline std::vector<world::Edit> one_edit_of_each_kind() {
  world::Stamp box;
  box.min = {-3.25f, 1, 2};
  box.max = {4, 5.5f, 6};
  box.material = 9;
  world::Stamp sphere;
  sphere.shape = world::Stamp::Shape::kSphere;
  sphere.center = {1e-7f, -2, 3};
  sphere.radius = 2.5f;
  sphere.solid = false;
  return {world::Brush{{1.5f, 2.25f, -3}, 4, 0.3f, true, std::nullopt},
          world::Brush{{0.1f, 0.2f, 0.3f}, 2, 0.5f, false, world::Material{7}},
          world::Explosion{{100, -50, 7.75f}, 12, 1.5f},
          world::Smooth{{3, 3, 3}, 5, 0.25f},
          world::Paint{{-8, 9, 10}, 3, 200},
          box,
          sphere};
}

}  // namespace vox::test
