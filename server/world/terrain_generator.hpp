// Deterministic terrain from a 64-bit seed: fBm hills, 3D-noise caves in a depth band,
// materials by depth. Chunks far above the hills (air) or below the cave band (rock) are
// recognised from the 32x32 column heights alone and returned uniform without sampling
// any 3D noise.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/gradient_noise.hpp"

namespace vox::world {

enum TerrainMaterial : Material { kGrass = 1, kDirt = 2, kStone = 3, kSand = 4 };

struct TerrainParams {
  float sea_level = 0.0f;          // mean surface height (voxels)
  float hill_height = 28.0f;       // surface varies by about +-hill_height
  float hill_wavelength = 160.0f;  // voxels per lowest-octave period
  int hill_octaves = 5;
  float cave_wavelength = 40.0f;
  float cave_threshold = 0.35f;     // air where cave noise exceeds this
  float cave_top_depth = 8.0f;      // caves start this far below the surface...
  float cave_bottom_depth = 96.0f;  // ...and stop this far below
};

// Surface heights of the 32x32 columns of one chunk column (all chunks with the same x, z
// share them), and their range.
struct ColumnHeights {
  std::array<float, kChunkSize * kChunkSize> height;  // x + 32 * z
  float min = 0, max = 0;
};

class TerrainGenerator {
 public:
  explicit TerrainGenerator(uint64_t seed, TerrainParams params = {});

  Chunk generate(ChunkCoord c) const;
  // The same chunk from precomputed heights of its column (column(c.x, c.z)); generating a
  // vertical stack of chunks computes the heights once.
  Chunk generate(ChunkCoord c, const ColumnHeights& heights) const;
  ColumnHeights column(int32_t cx, int32_t cz) const;
  // The sample the chunk containing (x, y, z) holds there; bit-identical to generate().
  Sample sample_at(int32_t x, int32_t y, int32_t z) const;
  float height_at(int32_t x, int32_t z) const;
  // sample_at(x, y0 + step * j, z) for j < n, into out[j * stride]: the column's height
  // once, cave noise only in the cave band.
  void sample_column(int32_t x, int32_t z, int32_t y0, int32_t step, int n, Sample* out,
                     ptrdiff_t stride) const;
  // sample_at(origin + step * (i, j, k)) into out[i + n[0] * (j + n[1] * k)], bit for bit:
  // heights once per column; on grids finer than the cave lattice, each lattice value
  // computed once (not eight times per sample). The calling thread only per `lattice`
  // (a reusable buffer).
  void sample_grid(const std::array<int32_t, 3>& origin, int32_t step, const std::array<int, 3>& n,
                   Sample* out, std::vector<float>& lattice) const;
  // Whether the grid lies wholly in the sky or in deep rock (sample_grid fills it with one
  // sample, computing no height).
  bool grid_is_uniform(int32_t y0, int32_t step, int ny) const;

  uint64_t seed() const { return seed_; }
  const TerrainParams& params() const { return params_; }

 private:
  static constexpr int kCaveStep = 4;  // caves are noise on a 4-voxel lattice, trilinear between
  float cave_lattice(int32_t i, int32_t j, int32_t k) const;
  // `cave` is the interpolated cave noise, or null when the chunk lies outside the band.
  Sample make_sample(float height, int32_t y, const float* cave) const;
  Sample sample_with_caves(float height, int32_t x, int32_t y, int32_t z) const;

  uint64_t seed_;
  TerrainParams params_;
  GradientNoise hills_;
  GradientNoise caves_;
  // Grids wholly above air_above_ are air, wholly below rock_below_ solid rock, whatever
  // the column heights (|fbm2| <= 1.5: each noise2 is a lerp of gradients |x +- y| <= 2,
  // times 0.7071): sample_grid fills them without computing a height (level-of-detail
  // chunks far above or below the hills).
  float air_above_ = 0, rock_below_ = 0;
  Sample air_{}, rock_{};
};

}  // namespace vox::world
