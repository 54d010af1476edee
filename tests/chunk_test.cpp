#include "server/world/chunk.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "server/world/chunk_map.hpp"

namespace vox::world {
namespace {

TEST(ChunkCoord, FloorDivisionPutsNegativeVoxelsInNegativeChunks) {
  EXPECT_EQ(chunk_of_voxel(0, 31, 32), (ChunkCoord{0, 0, 1}));
  EXPECT_EQ(chunk_of_voxel(-1, -32, -33), (ChunkCoord{-1, -1, -2}));
  EXPECT_EQ(floor_mod(-1, 32), 31);
  EXPECT_EQ(floor_mod(-32, 32), 0);
}

TEST(Sample, QuantisationKeepsSignAndClamps) {
  EXPECT_EQ(quantize_density(1e-9f), 1);
  EXPECT_EQ(quantize_density(0.0f), 0);
  EXPECT_EQ(quantize_density(-1e-9f), 0);
  EXPECT_EQ(quantize_density(7.0f), kDensityMax);
  EXPECT_EQ(quantize_density(-7.0f), kDensityMin);
  EXPECT_EQ(quantize_density(std::nanf("")), kDensityMin);
  EXPECT_NEAR(dequantize_density(quantize_density(0.123f)), 0.123f, 1.0f / 32767);
}

// ChunkMap::memory_bytes() is kept without a scan: it must equal the sum over the chunks.
TEST(ChunkMap, MemoryBytesFollowsInsertsErasesAndNotedChanges) {
  ChunkMap map;
  auto scanned = [&map] {  // what a scan of every chunk gives
    size_t bytes = map.bucket_bytes();
    for (const auto& [c, chunk] : map)
      bytes += sizeof(c) + 2 * sizeof(void*) + chunk.memory_bytes();
    return bytes;
  };
  Chunk full;
  full.set(1, 2, 3, Sample{100, 2});
  map.insert({0, 0, 0}, Chunk{});
  map.insert({1, 0, 0}, Chunk(full));
  map.insert({2, 0, 0}, Chunk(full));
  EXPECT_EQ(map.memory_bytes(), scanned());
  map.insert({2, 0, 0}, Chunk{});  // a full chunk replaced by a uniform one
  map.erase({1, 0, 0});
  map.erase({9, 9, 9});  // not there
  EXPECT_EQ(map.memory_bytes(), scanned());
  Chunk* c = map.find({0, 0, 0});
  const bool was = c->is_uniform();
  c->set(0, 0, 0, Sample{-5, 1});
  map.note_changed(was, *c);
  EXPECT_EQ(map.memory_bytes(), scanned());
  c->set(0, 0, 0, c->at(1, 1, 1));
  ASSERT_TRUE(c->compact());
  map.note_changed(false, *c);
  EXPECT_EQ(map.memory_bytes(), scanned());
}

TEST(Chunk, UniformChunkIsStoredAsOneValue) {
  Chunk air;
  EXPECT_TRUE(air.is_uniform());
  EXPECT_LE(sizeof(Chunk), 64u);
  EXPECT_LE(air.memory_bytes(), 64u);
  EXPECT_EQ(air.at(5, 6, 7), Sample{});
}

TEST(Chunk, FullChunkCostsAtMost100KiB) {
  Chunk c;
  c.set(1, 2, 3, {100, 2});
  EXPECT_FALSE(c.is_uniform());
  EXPECT_LE(c.memory_bytes(), 100u * 1024u);
  EXPECT_EQ(c.at(1, 2, 3), (Sample{100, 2}));
  EXPECT_EQ(c.at(3, 2, 1), Sample{});
}

TEST(Chunk, CompactReturnsToUniformWhenAllSamplesEqual) {
  Chunk c;
  c.set(1, 2, 3, {100, 2});
  EXPECT_FALSE(c.compact());
  c.set(1, 2, 3, Sample{});
  EXPECT_TRUE(c.compact());
  EXPECT_TRUE(c.is_uniform());
  EXPECT_EQ(c, Chunk{});
}

TEST(Chunk, CopyIsDeep) {
  Chunk a;
  a.set(0, 0, 0, {5, 1});
  Chunk b = a;
  b.set(0, 0, 0, {6, 1});
  EXPECT_EQ(a.at(0, 0, 0).density, 5);
  EXPECT_EQ(b.at(0, 0, 0).density, 6);
}

TEST(ChunkMap, SampleAtFindsNegativeChunksAndReportsMemory) {
  ChunkMap map;
  Chunk c;
  c.set(31, 0, 31, {77, 3});
  map.insert({-1, 0, -1}, std::move(c));
  map.insert({0, 0, 0}, Chunk(Sample{kDensityMax, 3}));
  EXPECT_EQ(map.sample_at(-1, 0, -1), (Sample{77, 3}));
  EXPECT_EQ(map.sample_at(5, 5, 5), (Sample{kDensityMax, 3}));
  EXPECT_EQ(map.sample_at(500, 5, 5), Sample{});  // not loaded: air
  EXPECT_EQ(map.size(), 2u);
  EXPECT_GE(map.memory_bytes(), 96u * 1024u);
  EXPECT_LT(map.memory_bytes(), 100u * 1024u + 1024u);
  EXPECT_TRUE(map.erase({0, 0, 0}));
  EXPECT_FALSE(map.erase({0, 0, 0}));
}

}  // namespace
}  // namespace vox::world
