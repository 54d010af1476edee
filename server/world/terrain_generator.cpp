#include "server/world/terrain_generator.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>

namespace vox::world {
namespace {

constexpr float kSurfaceRamp = 0.25f;  // density change per voxel of depth near the surface
constexpr float kCaveRamp = 8.0f;      // density change per unit of cave noise
constexpr float kCaveBandFade = 8.0f;  // voxels over which caves fade in at the band edges
constexpr float kCaveSealed = 10.0f;   // added to cave solidity outside the band: always solid
constexpr float kCaveNoiseLimit = 1.5f;

constexpr int kLattice = kChunkSize / 4 + 1;

// Cave noise between lattice points: bilinear in x then z on the lattice levels below and
// above, then linear in y. Chunk generation computes the per-level values once per
// column and reuses them; both paths use these same two functions, so results match.
inline float cave_level(float c00, float c10, float c01, float c11, float fx, float fz) {
  const float x0 = c00 + fx * (c10 - c00);
  const float x1 = c01 + fx * (c11 - c01);
  return x0 + fz * (x1 - x0);
}
inline float cave_between(float below, float above, float fy) {
  return below + fy * (above - below);
}

}  // namespace

TerrainGenerator::TerrainGenerator(uint64_t seed, TerrainParams params)
    : seed_(seed),
      params_(params),
      hills_(seed * 0x9E3779B97F4A7C15ull + 1),
      caves_(seed * 0xC2B2AE3D27D4EB4Full + 2) {
  const float reach = std::fabs(params_.hill_height) * 1.5f;
  air_above_ = params_.sea_level + reach + 1.0f / kSurfaceRamp + 1.0f;
  rock_below_ =
      params_.sea_level - reach -
      std::max({params_.cave_bottom_depth, params_.cave_top_depth, 6.0f, 1.0f / kSurfaceRamp}) -
      1.0f;
  air_ = make_sample(0.0f, static_cast<int32_t>(air_above_) + 1, nullptr);
  rock_ = make_sample(1e6f, 0, nullptr);
}

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

Sample TerrainGenerator::make_sample(float height, int32_t y, const float* cave) const {
  const float depth = height - static_cast<float>(y);
  if (depth <= -1.0f / kSurfaceRamp)
    return Sample{kDensityMin, kAir};  // open air: density clamps to -1
  float d = depth * kSurfaceRamp;
  const float band = std::clamp(
      std::min(depth - params_.cave_top_depth, params_.cave_bottom_depth - depth) / kCaveBandFade,
      0.0f, 1.0f);
  if (band > 0.0f && cave != nullptr) {
    const float solidity =
        (params_.cave_threshold - *cave) * kCaveRamp + (1.0f - band) * kCaveSealed;
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
  return sample_with_caves(height_at(x, z), x, y, z);
}

void TerrainGenerator::sample_column(int32_t x, int32_t z, int32_t y0, int32_t step, int n,
                                     Sample* out, ptrdiff_t stride) const {
  const float height = height_at(x, z);
  // On the cave lattice (coarse levels: every point a multiple of 4) the trilinear cave
  // noise has all fractions 0 and is the lattice value itself, bit for bit.
  const bool on_lattice = floor_mod(x, kCaveStep) == 0 && floor_mod(z, kCaveStep) == 0 &&
                          floor_mod(y0, kCaveStep) == 0 && step % kCaveStep == 0;
  for (int j = 0; j < n; ++j, out += stride) {
    const int32_t y = y0 + step * j;
    const float depth = height - static_cast<float>(y);
    // make_sample reads the cave noise only inside the band
    const bool in_band = depth > params_.cave_top_depth && depth < params_.cave_bottom_depth;
    if (!in_band) {
      *out = make_sample(height, y, nullptr);
    } else if (on_lattice) {
      const float cave =
          cave_lattice(floor_div(x, kCaveStep), floor_div(y, kCaveStep), floor_div(z, kCaveStep));
      *out = make_sample(height, y, &cave);
    } else {
      *out = sample_with_caves(height, x, y, z);
    }
  }
}

bool TerrainGenerator::grid_is_uniform(int32_t y0, int32_t step, int ny) const {
  return static_cast<float>(y0) > air_above_ ||
         static_cast<float>(int64_t{y0} + int64_t{step} * (ny - 1)) < rock_below_;
}

void TerrainGenerator::sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                                   const std::array<int, 3>& n, Sample* out,
                                   std::vector<float>& lattice) const {
  const ptrdiff_t row = n[0], layer = static_cast<ptrdiff_t>(n[0]) * n[1];
  if (grid_is_uniform(origin[1], step, n[1])) {
    std::fill(out, out + layer * n[2], static_cast<float>(origin[1]) > air_above_ ? air_ : rock_);
    return;
  }
  if (step >= kCaveStep) {  // coarse: no lattice value is shared between samples
    for (int k = 0; k < n[2]; ++k)
      for (int i = 0; i < n[0]; ++i)
        sample_column(origin[0] + step * i, origin[2] + step * k, origin[1], step, n[1],
                      out + i + layer * k, row);
    return;
  }
  // The lattice cells under the grid, computed on first use (NaN: not yet).
  std::array<int32_t, 3> lo{}, size{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = floor_div(origin[a], kCaveStep);
    size[a] = floor_div(origin[a] + step * (n[a] - 1), kCaveStep) + 2 - lo[a];
  }
  lattice.assign(static_cast<size_t>(size[0]) * size[1] * size[2], NAN);
  auto at = [&](int32_t i, int32_t j, int32_t k) {
    float& v =
        lattice[static_cast<size_t>((i - lo[0]) + size[0] * ((j - lo[1]) + size[1] * (k - lo[2])))];
    if (std::isnan(v)) v = cave_lattice(i, j, k);
    return v;
  };
  const float frac = 1.0f / kCaveStep;
  for (int k = 0; k < n[2]; ++k) {
    for (int i = 0; i < n[0]; ++i) {
      const int32_t x = origin[0] + step * i, z = origin[2] + step * k;
      const float height = height_at(x, z);
      const int32_t li = floor_div(x, kCaveStep), lk = floor_div(z, kCaveStep);
      const float fx = static_cast<float>(floor_mod(x, kCaveStep)) * frac,
                  fz = static_cast<float>(floor_mod(z, kCaveStep)) * frac;
      Sample* column = out + i + layer * k;
      // The column's cave noise on lattice levels lj and lj + 1 (as sample_with_caves makes
      // it), kept while the samples going up stay between them: the same values, each
      // level's four lattice reads once per column instead of once per sample.
      const auto level_at = [&](int32_t lj) {
        return cave_level(at(li, lj, lk), at(li + 1, lj, lk), at(li, lj, lk + 1),
                          at(li + 1, lj, lk + 1), fx, fz);
      };
      int32_t held = INT32_MIN;  // the lattice level of level[0] (none yet)
      float level[2] = {0, 0};
      for (int j = 0; j < n[1]; ++j) {
        const int32_t y = origin[1] + step * j;
        const float depth = height - static_cast<float>(y);
        if (!(depth > params_.cave_top_depth && depth < params_.cave_bottom_depth)) {
          column[row * j] = make_sample(height, y, nullptr);
          continue;
        }
        const int32_t lj = floor_div(y, kCaveStep);
        const float fy = static_cast<float>(floor_mod(y, kCaveStep)) * frac;
        if (lj == held + 1) {
          level[0] = level[1];
          level[1] = level_at(lj + 1);
        } else if (lj != held) {
          level[0] = level_at(lj);
          level[1] = level_at(lj + 1);
        }
        held = lj;
        const float cave = cave_between(level[0], level[1], fy);
        column[row * j] = make_sample(height, y, &cave);
      }
    }
  }
}

Sample TerrainGenerator::sample_with_caves(float height, int32_t x, int32_t y, int32_t z) const {
  const int32_t i = floor_div(x, kCaveStep), j = floor_div(y, kCaveStep),
                k = floor_div(z, kCaveStep);
  const float step = 1.0f / kCaveStep;
  const float fx = static_cast<float>(floor_mod(x, kCaveStep)) * step,
              fy = static_cast<float>(floor_mod(y, kCaveStep)) * step,
              fz = static_cast<float>(floor_mod(z, kCaveStep)) * step;
  float level[2];
  for (int l = 0; l < 2; ++l) {
    level[l] = cave_level(cave_lattice(i, j + l, k), cave_lattice(i + 1, j + l, k),
                          cave_lattice(i, j + l, k + 1), cave_lattice(i + 1, j + l, k + 1), fx, fz);
  }
  const float cave = cave_between(level[0], level[1], fy);
  return make_sample(height, y, &cave);
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

  const bool caves =
      hmax - y_bottom > params_.cave_top_depth && min_depth < params_.cave_bottom_depth;
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
  std::array<float, kLattice> levels;  // cave noise of this column at each lattice level
  for (int z = 0; z < kChunkSize; ++z) {
    for (int x = 0; x < kChunkSize; ++x) {
      const float height = heights[x + kChunkSize * z];
      if (caves) {
        const int li = x / kCaveStep, lk = z / kCaveStep;
        const float fx = static_cast<float>(x % kCaveStep) * kStepInv,
                    fz = static_cast<float>(z % kCaveStep) * kStepInv;
        for (int j = 0; j < kLattice; ++j) {
          const auto at = [&](int di, int dk) {
            return lattice[(li + di) + kLattice * (j + kLattice * (lk + dk))];
          };
          levels[j] = cave_level(at(0, 0), at(1, 0), at(0, 1), at(1, 1), fx, fz);
        }
      }
      for (int y = 0; y < kChunkSize; ++y) {
        float cave = 0;
        if (caves)
          cave = cave_between(levels[y / kCaveStep], levels[y / kCaveStep + 1],
                              static_cast<float>(y % kCaveStep) * kStepInv);
        const Sample s = make_sample(height, y0 + y, caves ? &cave : nullptr);
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
