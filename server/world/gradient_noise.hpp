// Seeded gradient noise (Perlin's improved noise: quintic fade, hashed lattice gradients)
// in 2D and 3D, plus fractal Brownian motion. Pure functions of (seed, position): the same
// inputs give the same bits on every thread and in every call order.
#pragma once

#include <cstdint>

namespace vox::world {

class GradientNoise {
 public:
  explicit GradientNoise(uint64_t seed) : seed_(seed) {}

  float noise2(float x, float y) const;           // about [-1, 1]
  float noise3(float x, float y, float z) const;  // about [-1, 1]
  // Sum of `octaves` layers, frequency x2 and amplitude x0.5 per layer, normalised to
  // about [-1, 1].
  float fbm2(float x, float y, int octaves) const;
  float fbm3(float x, float y, float z, int octaves) const;

 private:
  uint32_t hash(int32_t x, int32_t y, int32_t z, uint32_t octave) const;

  uint64_t seed_;
};

}  // namespace vox::world
