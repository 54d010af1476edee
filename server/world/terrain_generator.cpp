#include "world/terrain_generator.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace vox::world {
namespace {

constexpr float kSurfaceRamp = 0.25f;  // density change per voxel of depth near the surface
constexpr float kCaveRamp = 8.0f;      // density change per unit of cave noise
constexpr float kCaveBandFade = 8.0f;  // voxels over which caves fade in at the band edges
constexpr float kCaveSealed = 10.0f;   // added to cave solidity outside the band: always solid
constexpr float kCaveNoiseLimit = 1.5f;

constexpr int kLattice = kChunkSize / 4 + 1;

inline float trilinear(const float* c, float fx, float fy, float fz) {
  const float x00 = c[0] + fx * (c[1] - c[0]);
  const float x10 = c[2] + fx * (c[3] - c[2]);
  const float x01 = c[4] + fx * (c[5] - c[4]);
  const float x11 = c[6] + fx * (c[7] - c[6]);
  const float y0 = x00 + fy * (x10 - x00);
  const float y1 = x01 + fy * (x11 - x01);
  return y0 + fz * (y1 - y0);
}

}  // namespace

TerrainGenerator::TerrainGenerator(uint64_t seed, TerrainParams params)
    : seed_(seed),
      params_(params),
      hills_(seed * 0x9E3779B97F4A7C15ull + 1),
      caves_(seed * 0xC2B2AE3D27D4EB4Full + 2) {}

float TerrainGenerator::height_at(int32_t x, int32_t z) const {
  const float f = 1.0f / params_.hill_wavelength;
  return params_.sea_level + params_.hill_height * hills_.fbm2(static_cast<float>(x) * f,
                                                               static_cast<float>(z) * f,
                                                               params_.hill_octaves);
}

float TerrainGenerator::cave_lattice(int32_t i, int32_t j, int32_t k) const {
  const float f = static_cast<float>(kCaveStep) / params_.cave_wavelength;
  const float n = caves_.fbm3(static_cast<float>(i) * f, static_cast<float>(j) * f,
                              static_cast<float>(k) * f, 2);
  return std::clamp(n, -kCaveNoiseLimit, kCaveNoiseLimit);
}

// cave_corners: the 8 lattice values around the sample (x fastest), or null when the
// whole chunk lies outside the cave band.
Sample TerrainGenerator::make_sample(float height, int32_t y, const float* cave_corners,
                                     float fx, float fy, float fz) const {
  const float depth = height - static_cast<float>(y);
  float d = depth * kSurfaceRamp;
  const float band = std::clamp(
      std::min(depth - params_.cave_top_depth, params_.cave_bottom_depth - depth) / kCaveBandFade,
      0.0f, 1.0f);
  if (band > 0.0f && cave_corners != nullptr) {
    const float c = trilinear(cave_corners, fx, fy, fz);
    const float solidity = (params_.cave_threshold - c) * kCaveRamp + (1.0f - band) * kCaveSealed;
    d = std::min(d, solidity);
  }
  Sample s{quantize_density(d), kAir};
  if (is_solid(s.density)) {
    if (depth < 1.5f) {
      s.material = height < params_.sea_level - 10.0f ? kSand : kGrass;
    } else if (depth < 6.0f) {
      s.material = kDirt;
    } else {
      s.material = kStone;
    }
  }
  return s;
}

Sample TerrainGenerator::sample_at(int32_t x, int32_t y, int32_t z) const {
  const float height = height_at(x, z);
  const int32_t i = floor_div(x, kCaveStep), j = floor_div(y, kCaveStep), k = floor_div(z, kCaveStep);
  float corners[8];
  for (int c = 0; c < 8; ++c) corners[c] = cave_lattice(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
  const float step = 1.0f / kCaveStep;
  return make_sample(height, y, corners, static_cast<float>(floor_mod(x, kCaveStep)) * step,
                     static_cast<float>(floor_mod(y, kCaveStep)) * step,
                     static_cast<float>(floor_mod(z, kCaveStep)) * step);
}

ColumnHeights TerrainGenerator::column(int32_t cx, int32_t cz) const {
  ColumnHeights col;
  col.min = INFINITY;
  col.max = -INFINITY;
  for (int z = 0; z < kChunkSize; ++z) {
    for (int x = 0; x < kChunkSize; ++x) {
      const float h = height_at(cx * kChunkSize + x, cz * kChunkSize + z);
      col.height[x + kChunkSize * z] = h;
      col.min = std::min(col.min, h);
      col.max = std::max(col.max, h);
    }
  }
  return col;
}

Chunk TerrainGenerator::generate(ChunkCoord c) const { return generate(c, column(c.x, c.z)); }

Chunk TerrainGenerator::generate(ChunkCoord c, const ColumnHeights& column) const {
  const int32_t y0 = c.y * kChunkSize;
  const auto& heights = column.height;
  const float hmin = column.min, hmax = column.max;
  const float y_top = static_cast<float>(y0 + kChunkSize - 1);
  const float y_bottom = static_cast<float>(y0);
  // Open sky: every depth <= -4, so every density clamps to -1.
  if (y_bottom - hmax >= 1.0f / kSurfaceRamp) return Chunk(Sample{kDensityMin, kAir});
  // Deep rock: below the cave band and deep enough that the surface ramp saturates.
  const float min_depth = hmin - y_top;
  if (min_depth >= params_.cave_bottom_depth && min_depth >= 1.0f / kSurfaceRamp) {
    return Chunk(Sample{kDensityMax, kStone});
  }

  const bool caves = hmax - y_bottom > params_.cave_top_depth && min_depth < params_.cave_bottom_depth;
  std::array<float, kLattice * kLattice * kLattice> lattice;
  if (caves) {
    const int32_t i0 = c.x * (kChunkSize / kCaveStep), j0 = c.y * (kChunkSize / kCaveStep),
                  k0 = c.z * (kChunkSize / kCaveStep);
    for (int k = 0; k < kLattice; ++k)
      for (int j = 0; j < kLattice; ++j)
        for (int i = 0; i < kLattice; ++i)
          lattice[i + kLattice * (j + kLattice * k)] = cave_lattice(i0 + i, j0 + j, k0 + k);
  }

  Chunk chunk;
  Density* dens = chunk.densities();
  Material* mats = chunk.materials();
  constexpr float kStepInv = 1.0f / kCaveStep;
  float corners[8];
  for (int z = 0; z < kChunkSize; ++z) {
    for (int y = 0; y < kChunkSize; ++y) {
      for (int x = 0; x < kChunkSize; ++x) {
        const float* cave_corners = nullptr;
        if (caves) {
          const int li = x / kCaveStep, lj = y / kCaveStep, lk = z / kCaveStep;
          for (int n = 0; n < 8; ++n) {
            corners[n] = lattice[(li + (n & 1)) + kLattice * ((lj + ((n >> 1) & 1)) +
                                                              kLattice * (lk + (n >> 2)))];
          }
          cave_corners = corners;
        }
        const Sample s = make_sample(heights[x + kChunkSize * z], y0 + y, cave_corners,
                                     static_cast<float>(x % kCaveStep) * kStepInv,
                                     static_cast<float>(y % kCaveStep) * kStepInv,
                                     static_cast<float>(z % kCaveStep) * kStepInv);
        const int idx = Chunk::index(x, y, z);
        dens[idx] = s.density;
        mats[idx] = s.material;
      }
    }
  }
  chunk.compact();
  return chunk;
}

}  // namespace vox::world
