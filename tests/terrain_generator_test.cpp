#include "server/world/terrain_generator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "server/world/parallel.hpp"
#include "server/world/terrain_sampler.hpp"

namespace vox::world {
namespace {

std::vector<ChunkCoord> region(int r) {
  std::vector<ChunkCoord> coords;
  for (int z = -r; z < r; ++z)
    for (int y = -4; y < 2; ++y)
      for (int x = -r; x < r; ++x) coords.push_back({x, y, z});
  return coords;
}

TEST(TerrainGenerator, SameSeedGivesIdenticalChunksWhateverThreadsOrOrder) {
  const TerrainGenerator gen(42);
  const auto coords = region(3);
  std::vector<Chunk> serial;
  for (const auto& c : coords) serial.push_back(gen.generate(c));

  for (int threads : {1, 2, 4}) {
    std::vector<size_t> order(coords.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), std::mt19937(threads));
    std::vector<Chunk> parallel(coords.size());
    tbb::task_arena arena(threads);
    parallel_for_index(arena, order.size(), [&](size_t k) {
      parallel[order[k]] = TerrainGenerator(42).generate(coords[order[k]]);
    });
    for (size_t i = 0; i < coords.size(); ++i)
      ASSERT_EQ(parallel[i], serial[i]) << "chunk " << i << " threads " << threads;
  }
}

// FNV-1a over what the generator gives: chunks, coarse grids and the raw noise. A world
// keeps only the chunks that differ from its generated terrain, so the terrain of a seed
// may never change, however the code computing it is made faster: these values were
// taken from the generator at commit 6334499, before its noise was made branchless.
uint64_t fnv(uint64_t h, const void* data, size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 0x100000001B3ull;
  return h;
}

TEST(TerrainGenerator, TheTerrainOfASeedNeverChanges) {
  const TerrainGenerator gen(42);
  uint64_t chunks = 0xCBF29CE484222325ull;
  for (const ChunkCoord& c : region(3)) {
    const Chunk chunk = gen.generate(c);
    for (int i = 0; i < kChunkVolume; ++i) {
      const Sample s = chunk.at(i);
      chunks = fnv(chunks, &s.density, sizeof s.density);
      chunks = fnv(chunks, &s.material, sizeof s.material);
    }
  }
  uint64_t grids = 0xCBF29CE484222325ull;
  const TerrainSampler sampler(gen);
  for (const int step : {2, 4, 8, 32}) {
    const std::array<int, 3> n{35, 35, 35};
    std::vector<Sample> grid(static_cast<size_t>(n[0]) * n[1] * n[2]);
    sampler.sample_grid({-17 * step - 3, -20 * step, 11 * step + 1}, step, n, grid.data());
    for (const Sample& s : grid) {
      grids = fnv(grids, &s.density, sizeof s.density);
      grids = fnv(grids, &s.material, sizeof s.material);
    }
  }
  uint64_t noise = 0xCBF29CE484222325ull;
  const GradientNoise g(7);
  for (int i = 0; i < 4000; ++i) {
    const float x = static_cast<float>(i) * 0.37f - 700.0f, y = static_cast<float>(i % 97) * -1.3f,
                z = static_cast<float>(i % 31) * 2.1f + 0.5f;
    const float v[4] = {g.noise2(x, y), g.noise3(x, y, z), g.fbm2(x, z, 5), g.fbm3(z, x, y, 2)};
    noise = fnv(noise, v, sizeof v);
  }
  EXPECT_EQ(chunks, 1749264282403933431u);
  EXPECT_EQ(grids, 16924851473781437618u);
  EXPECT_EQ(noise, 1955888558993509276u);
}

TEST(TerrainGenerator, DifferentSeedsGiveDifferentTerrain) {
  EXPECT_NE(TerrainGenerator(1).height_at(100, 100), TerrainGenerator(2).height_at(100, 100));
}

TEST(TerrainGenerator, PointSamplesEqualChunkSamples) {
  const TerrainGenerator gen(7);
  std::mt19937 rng(3);
  for (const ChunkCoord c : {ChunkCoord{0, -1, 0}, ChunkCoord{-2, 0, 3}, ChunkCoord{1, -2, -1}}) {
    const Chunk chunk = gen.generate(c);
    for (int k = 0; k < 500; ++k) {
      const int x = static_cast<int>(rng() % 32), y = static_cast<int>(rng() % 32),
                z = static_cast<int>(rng() % 32);
      ASSERT_EQ(chunk.at(x, y, z), gen.sample_at(c.x * 32 + x, c.y * 32 + y, c.z * 32 + z));
    }
  }
}

TEST(TerrainGenerator, ColumnsAndGridsOfPointsEqualPointSamples) {
  const TerrainGenerator gen(7);
  const TerrainSampler sampler(gen);
  std::mt19937 rng(5);
  for (const int step : {1, 2, 4, 8, 64}) {
    for (const bool aligned : {false, true}) {  // aligned: every point on the cave lattice
      // Columns from deep rock through the cave band to the sky.
      std::array<int32_t, 3> origin{static_cast<int32_t>(rng() % 4000) - 2000, -40 * step,
                                    static_cast<int32_t>(rng() % 4000) - 2000};
      if (aligned) {
        origin[0] = floor_div(origin[0], 4) * 4;
        origin[2] = floor_div(origin[2], 4) * 4;
      }
      const std::array<int, 3> n{5, 80, 4};
      std::vector<Sample> grid(static_cast<size_t>(n[0] * n[1] * n[2]));
      sampler.sample_grid(origin, step, n, grid.data());
      for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
          for (int i = 0; i < n[0]; ++i)
            ASSERT_EQ(
                grid[static_cast<size_t>(i + n[0] * (j + n[1] * k))],
                gen.sample_at(origin[0] + step * i, origin[1] + step * j, origin[2] + step * k))
                << "step " << step << (aligned ? ", aligned" : "");
    }
  }
  // A whole chunk's grid equals the chunk generated.
  for (const ChunkCoord c : {ChunkCoord{0, -1, 0}, ChunkCoord{-3, -2, 5}}) {
    const Chunk chunk = gen.generate(c);
    std::vector<Sample> grid(kChunkVolume);
    sampler.sample_grid({c.x * kChunkSize, c.y * kChunkSize, c.z * kChunkSize}, 1,
                        {kChunkSize, kChunkSize, kChunkSize}, grid.data());
    for (int i = 0; i < kChunkVolume; ++i) ASSERT_EQ(grid[static_cast<size_t>(i)], chunk.at(i));
  }
}

// Grids wholly in the sky or in deep rock are filled without heights: still bit for bit
// the point samples, right up to the bounds (the hills' extremes over many columns).
TEST(TerrainGenerator, GridsInTheSkyOrDeepRockEqualPointSamples) {
  for (const uint64_t seed : {1u, 9u}) {
    const TerrainGenerator gen(seed);
    const TerrainSampler sampler(gen);
    float lowest = 1e9f, highest = -1e9f;
    for (int z = -4000; z <= 4000; z += 37)
      for (int x = -4000; x <= 4000; x += 41) {
        lowest = std::min(lowest, gen.height_at(x, z));
        highest = std::max(highest, gen.height_at(x, z));
      }
    // Every y from well below the lowest hill minus the cave band to well above the top.
    for (int y0 = static_cast<int>(lowest) - 200; y0 <= static_cast<int>(highest) + 60; y0 += 7) {
      for (const int step : {1, 4, 16}) {
        const std::array<int32_t, 3> origin{-301, y0, 977};
        const std::array<int, 3> n{3, 3, 3};
        std::vector<Sample> grid(27);
        sampler.sample_grid(origin, step, n, grid.data());
        for (int k = 0; k < 3; ++k)
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i)
              ASSERT_EQ(grid[static_cast<size_t>(i + 3 * (j + 3 * k))],
                        gen.sample_at(origin[0] + step * i, y0 + step * j, origin[2] + step * k))
                  << "seed " << seed << " y " << y0 << " step " << step;
      }
    }
  }
}

TEST(TerrainGenerator, SkyAndDeepRockAreUniform) {
  const TerrainGenerator gen(9);
  const Chunk sky = gen.generate({0, 10, 0});
  ASSERT_TRUE(sky.is_uniform());
  EXPECT_FALSE(is_solid(sky.uniform_value().density));
  const Chunk rock = gen.generate({0, -10, 0});
  ASSERT_TRUE(rock.is_uniform());
  EXPECT_EQ(rock.uniform_value(), (Sample{kDensityMax, kStone}));
}

TEST(TerrainGenerator, SurfaceHasThreeMaterialsByDepthAndCaves) {
  const TerrainGenerator gen(5);
  std::set<Material> materials;
  size_t cave_air = 0;
  for (const auto& c : region(3)) {
    const Chunk chunk = gen.generate(c);
    for (int i = 0; i < kChunkVolume; ++i) {
      const Sample s = chunk.at(i);
      if (is_solid(s.density)) materials.insert(s.material);
    }
    // Air well below the local surface is a cave.
    for (int z = 0; z < 32; z += 4)
      for (int x = 0; x < 32; x += 4)
        for (int y = 0; y < 32; ++y) {
          const int wy = c.y * 32 + y;
          if (gen.height_at(c.x * 32 + x, c.z * 32 + z) - wy > 12 &&
              !is_solid(chunk.at(x, y, z).density))
            ++cave_air;
        }
  }
  EXPECT_GE(materials.size(), 3u);
  EXPECT_TRUE(materials.count(kGrass) && materials.count(kDirt) && materials.count(kStone));
  EXPECT_GT(cave_air, 0u);
}

}  // namespace
}  // namespace vox::world
