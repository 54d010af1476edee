// Gradient noise after K. Perlin, "Improving Noise" (SIGGRAPH 2002): fade 6t^5-15t^4+10t^3
// and gradients from a fixed set of directions. The permutation table is replaced by an
// integer hash of (seed, lattice point), so any seed works without tables.
#include "server/world/gradient_noise.hpp"

#include <cmath>

namespace vox::world {
namespace {

inline float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
inline float lerp(float a, float b, float t) { return a + t * (b - a); }

inline float grad2(uint32_t h, float x, float y) {
  switch (h & 7u) {
    case 0:
      return x + y;
    case 1:
      return -x + y;
    case 2:
      return x - y;
    case 3:
      return -x - y;
    case 4:
      return x;
    case 5:
      return -x;
    case 6:
      return y;
    default:
      return -y;
  }
}

// The 12 cube-edge directions of improved noise (16 entries, 4 repeated).
inline float grad3(uint32_t h, float x, float y, float z) {
  switch (h & 15u) {
    case 0:
      return x + y;
    case 1:
      return -x + y;
    case 2:
      return x - y;
    case 3:
      return -x - y;
    case 4:
      return x + z;
    case 5:
      return -x + z;
    case 6:
      return x - z;
    case 7:
      return -x - z;
    case 8:
      return y + z;
    case 9:
      return -y + z;
    case 10:
      return y - z;
    case 11:
      return -y - z;
    case 12:
      return x + y;
    case 13:
      return -y + z;
    case 14:
      return -x + y;
    default:
      return -y - z;
  }
}

}  // namespace

// Lattice hash: the coordinates mixed with odd constants, then the MurmurHash3 32-bit
// finaliser. Cheap enough to run 4-8 times per noise sample.
uint32_t GradientNoise::hash(int32_t x, int32_t y, int32_t z, uint32_t octave) const {
  uint32_t h =
      static_cast<uint32_t>(seed_) ^ static_cast<uint32_t>(seed_ >> 32) ^ (octave * 0x9E3779B9u);
  h ^= static_cast<uint32_t>(x) * 0x85EBCA6Bu;
  h ^= static_cast<uint32_t>(y) * 0xC2B2AE35u;
  h ^= static_cast<uint32_t>(z) * 0x27D4EB2Fu;
  h ^= h >> 16;
  h *= 0x85EBCA6Bu;
  h ^= h >> 13;
  h *= 0xC2B2AE35u;
  h ^= h >> 16;
  return h;
}

float GradientNoise::noise2(float x, float y) const {
  const float fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy);
  const float dx = x - fx, dy = y - fy;
  const float n00 = grad2(hash(ix, iy, 0, 0), dx, dy);
  const float n10 = grad2(hash(ix + 1, iy, 0, 0), dx - 1, dy);
  const float n01 = grad2(hash(ix, iy + 1, 0, 0), dx, dy - 1);
  const float n11 = grad2(hash(ix + 1, iy + 1, 0, 0), dx - 1, dy - 1);
  const float u = fade(dx), v = fade(dy);
  return lerp(lerp(n00, n10, u), lerp(n01, n11, u), v) * 0.7071f;
}

float GradientNoise::noise3(float x, float y, float z) const {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const auto ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy),
             iz = static_cast<int32_t>(fz);
  const float dx = x - fx, dy = y - fy, dz = z - fz;
  const float u = fade(dx), v = fade(dy), w = fade(dz);
  float layer[2];
  for (int k = 0; k < 2; ++k) {
    const float gz = dz - static_cast<float>(k);
    const float n00 = grad3(hash(ix, iy, iz + k, 1), dx, dy, gz);
    const float n10 = grad3(hash(ix + 1, iy, iz + k, 1), dx - 1, dy, gz);
    const float n01 = grad3(hash(ix, iy + 1, iz + k, 1), dx, dy - 1, gz);
    const float n11 = grad3(hash(ix + 1, iy + 1, iz + k, 1), dx - 1, dy - 1, gz);
    layer[k] = lerp(lerp(n00, n10, u), lerp(n01, n11, u), v);
  }
  return lerp(layer[0], layer[1], w);
}

float GradientNoise::fbm2(float x, float y, int octaves) const {
  float sum = 0, amplitude = 1, norm = 0;
  for (int o = 0; o < octaves; ++o) {
    // Offset each octave so their lattices do not line up at the origin.
    sum +=
        amplitude * noise2(x + 17.13f * static_cast<float>(o), y - 31.7f * static_cast<float>(o));
    norm += amplitude;
    amplitude *= 0.5f;
    x *= 2.0f;
    y *= 2.0f;
  }
  return sum / norm;
}

float GradientNoise::fbm3(float x, float y, float z, int octaves) const {
  float sum = 0, amplitude = 1, norm = 0;
  for (int o = 0; o < octaves; ++o) {
    const float shift = 13.37f * static_cast<float>(o);
    sum += amplitude * noise3(x + shift, y - shift, z + 0.5f * shift);
    norm += amplitude;
    amplitude *= 0.5f;
    x *= 2.0f;
    y *= 2.0f;
    z *= 2.0f;
  }
  return sum / norm;
}

}  // namespace vox::world
