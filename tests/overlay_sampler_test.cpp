// The sampler of an edited world (server/world/overlay_sampler.hpp) and what it gives the
// level-of-detail meshes: every level shows an edit made at level 0.
#include "server/world/overlay_sampler.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <stdexcept>

#include "server/mesh/lod_mesher.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/terrain_sampler.hpp"

namespace vox::world {
namespace {

// A big explosion near the surface of seed 3, applied to the level-0 chunks it touches.
struct EditedWorld {
  TerrainGenerator generator{3};
  ChunkMap chunks;
  OverlaySampler::ModifiedSet modified;
  Vec3 centre;
  float radius = 40.0f;

  EditedWorld() {
    centre = {100.0f, generator.height_at(100, 60), 60.0f};
    const Explosion blast{centre, radius, 4.0f};
    const VoxelBox box{
        {static_cast<int32_t>(centre.x - radius - 1), static_cast<int32_t>(centre.y - radius - 1),
         static_cast<int32_t>(centre.z - radius - 1)},
        {static_cast<int32_t>(centre.x + radius + 1), static_cast<int32_t>(centre.y + radius + 1),
         static_cast<int32_t>(centre.z + radius + 1)}};
    for (const ChunkCoord c : chunks_overlapping(box)) {
      Chunk chunk = generator.generate(c);
      if (apply_edit(blast, c, chunk, nullptr).changed) {
        chunks.insert(c, std::move(chunk));
        modified.insert(c);
      }
    }
  }
  OverlaySampler sampler() const {
    return OverlaySampler(generator, modified, [this](ChunkCoord c) -> const Chunk& {
      const Chunk* chunk = chunks.find(c);
      if (chunk == nullptr) throw std::logic_error("modified chunk missing");
      return *chunk;
    });
  }
  Sample reference(int32_t x, int32_t y, int32_t z) const {
    const ChunkCoord c = chunk_of_voxel(x, y, z);
    if (!modified.contains(c)) return generator.sample_at(x, y, z);
    return chunks.find(c)->at(x - c.x * kChunkSize, y - c.y * kChunkSize, z - c.z * kChunkSize);
  }
};

TEST(OverlaySampler, ModifiedChunksReplaceTheGeneratorsSamplesOnEveryGrid) {
  const EditedWorld world;
  ASSERT_GT(world.modified.size(), 8u);
  const OverlaySampler sampler = world.sampler();
  std::mt19937 rng(4);
  // Small grids (the box has fewer chunks than the set) and large ones (more).
  for (const int step : {1, 2, 4, 8, 64}) {
    for (int trial = 0; trial < 4; ++trial) {
      const std::array<int, 3> n{9 + static_cast<int>(rng() % 20), 7, 11};
      const std::array<int32_t, 3> origin{
          static_cast<int32_t>(world.centre.x) - step * n[0] / 2 + static_cast<int32_t>(rng() % 7),
          static_cast<int32_t>(world.centre.y) - step * 3 - static_cast<int32_t>(rng() % 5),
          static_cast<int32_t>(world.centre.z) - step * 5 + static_cast<int32_t>(rng() % 9)};
      std::vector<Sample> grid(static_cast<size_t>(n[0] * n[1] * n[2]));
      sampler.sample_grid(origin, step, n, grid.data());
      size_t from_edit = 0;
      for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
          for (int i = 0; i < n[0]; ++i) {
            const int32_t x = origin[0] + step * i, y = origin[1] + step * j,
                          z = origin[2] + step * k;
            const Sample want = world.reference(x, y, z);
            ASSERT_EQ(grid[static_cast<size_t>(i + n[0] * (j + n[1] * k))], want)
                << "step " << step << " at " << x << ", " << y << ", " << z;
            from_edit += want != world.generator.sample_at(x, y, z);
          }
      if (step <= 8) {
        EXPECT_GT(from_edit, 0u) << "step " << step;
      }
    }
  }
}

// A crater 80 voxels wide made at level 0 shows in the level-1, -2 and -3 meshes over it,
// which lie within 2^k voxels of the edited level-0 surface.
TEST(OverlaySampler, AnEditAtLevelZeroShowsInEveryCoarserLevel) {
  const EditedWorld world;
  const OverlaySampler edited = world.sampler();
  const TerrainSampler plain(world.generator);
  mesh::LodBlock block;
  mesh::LodScratch scratch;
  mesh::ChunkMesh before, after;
  for (int level = 1; level <= 3; ++level) {
    const int32_t side = kChunkSize << level;
    const LodChunk c{level,
                     {floor_div(static_cast<int32_t>(world.centre.x), side),
                      floor_div(static_cast<int32_t>(world.centre.y), side),
                      floor_div(static_cast<int32_t>(world.centre.z), side)}};
    mesh::gather_lod_block(plain, c, {}, block);
    mesh::mesh_lod_chunk(block, scratch, before);
    mesh::gather_lod_block(edited, c, {}, block);
    mesh::mesh_lod_chunk(block, scratch, after);
    ASSERT_FALSE(after.empty());
    EXPECT_NE(before.positions, after.positions) << "level " << level;
    const int reach = 1 << level;
    const auto lo = c.lo();
    for (size_t v = 0; v < after.vertex_count(); v += 7) {
      const mesh::Vec3f p = after.positions[v];
      const float w[3] = {static_cast<float>(lo[0]) + p.x * static_cast<float>(reach),
                          static_cast<float>(lo[1]) + p.y * static_cast<float>(reach),
                          static_cast<float>(lo[2]) + p.z * static_cast<float>(reach)};
      bool solid = false, air = false;
      for (int z = static_cast<int>(std::ceil(w[2])) - reach; z <= std::floor(w[2]) + reach; ++z)
        for (int y = static_cast<int>(std::ceil(w[1])) - reach; y <= std::floor(w[1]) + reach; ++y)
          for (int x = static_cast<int>(std::ceil(w[0])) - reach; x <= std::floor(w[0]) + reach;
               ++x)
            (is_solid(world.reference(x, y, z).density) ? solid : air) = true;
      ASSERT_TRUE(solid && air) << "level " << level << " vertex " << w[0] << ", " << w[1] << ", "
                                << w[2];
    }
  }
}

// The generator grids kept for reuse (grid_cache.hpp): a grid sampled twice through a
// cache is the same, the second time from the cache; the cache stays within its bytes,
// dropping the least recently used grid.
TEST(GridCache, AGridFromTheCacheEqualsTheGeneratorsAndTheCacheStaysBounded) {
  const TerrainGenerator generator(3);
  const OverlaySampler::ModifiedSet none;
  GridCache cache(16 * 1024);
  const OverlaySampler sampler(
      generator, none, [](ChunkCoord) -> const Chunk& { throw std::logic_error("no lookup"); },
      &cache);
  const std::array<int, 3> n{10, 10, 10};
  std::vector<Sample> first(1000), second(1000), direct(1000);
  std::vector<float> lattice;
  for (int i = 0; i < 40; ++i) {
    // Through the surface and the caves: grids of many runs.
    const std::array<int32_t, 3> origin{i * 17, -15, 3};
    sampler.sample_grid(origin, 2, n, first.data());
    sampler.sample_grid(origin, 2, n, second.data());
    generator.sample_grid(origin, 2, n, direct.data(), lattice);
    ASSERT_EQ(first, direct);
    ASSERT_EQ(second, direct);
    EXPECT_LE(cache.bytes(), 16u * 1024);
  }
  EXPECT_GT(cache.bytes(), 8u * 1024);
  Sample probe[1000];
  EXPECT_TRUE(cache.get({{39 * 17, -15, 3}, 2, n}, probe)) << "the newest grid is kept";
  EXPECT_FALSE(cache.get({{0, -15, 3}, 2, n}, probe)) << "the oldest was dropped";
}

// A 64 MB cache held only a few hundred coarse chunks' grids, 171 KB each, while a crowd's
// first views want each chunk again for every seams variant, one player at a time: the
// grids were sampled again and again. Kept as runs, a coarse chunk's grid through the
// surface takes under a fifth of its samples' bytes, and reads back the same.
TEST(GridCache, ACoarseGridThroughTheSurfaceIsKeptInAFifthOfItsSamplesBytes) {
  const TerrainGenerator generator(1);
  std::vector<float> lattice;
  constexpr int kSide = 35;
  const std::array<int, 3> n{kSide, kSide, kSide};
  std::vector<Sample> grid(kSide * kSide * kSide), back(grid.size());
  for (const int32_t step : {2, 8, 32}) {
    GridCache cache(size_t{64} << 20);
    const std::array<int32_t, 3> origin{-step * 7, -step * 17, step * 3};
    generator.sample_grid(origin, step, n, grid.data(), lattice);
    cache.put({origin, step, n}, grid.data());
    EXPECT_LT(cache.bytes(), grid.size() * sizeof(Sample) / 5) << "step " << step;
    ASSERT_TRUE(cache.get({origin, step, n}, back.data()));
    EXPECT_EQ(back, grid) << "step " << step;
  }
}

}  // namespace
}  // namespace vox::world
