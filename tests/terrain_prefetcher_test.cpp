#include "server/pipeline/terrain_prefetcher.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

namespace vox::pipeline {
namespace {

using world::ChunkCoord;

// Collects ready chunks until `want` have arrived (or 30 s pass).
std::map<ChunkCoord, world::Chunk> collect(TerrainPrefetcher& p, size_t want) {
  std::map<ChunkCoord, world::Chunk> got;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (got.size() < want && std::chrono::steady_clock::now() < deadline) {
    for (auto& [c, chunk] : p.take_ready()) got.emplace(c, std::move(chunk));
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return got;
}

TEST(TerrainPrefetcher, GeneratesInTheBackgroundExactlyWhatTheGeneratorMakes) {
  const world::TerrainGenerator gen(7);
  std::atomic<int> notified{0};
  TerrainPrefetcher p(gen, 2, 1000, 1000, [&] { ++notified; });
  std::vector<ChunkCoord> want;
  for (int y = -2; y <= 1; ++y)
    for (int x = 0; x < 4; ++x) want.push_back({x, y, 3});
  EXPECT_TRUE(p.request(want).empty());
  for (const ChunkCoord& c : want) EXPECT_TRUE(p.pending(c));
  const auto got = collect(p, want.size());
  ASSERT_EQ(got.size(), want.size());
  for (const ChunkCoord& c : want)
    EXPECT_TRUE(got.at(c) == gen.generate(c)) << "chunk differs from inline generation";
  EXPECT_GT(notified.load(), 0);
  EXPECT_EQ(p.pending_count(), 0u) << "taken chunks are no longer pending";
  EXPECT_FALSE(p.pending(want[0]));
}

TEST(TerrainPrefetcher, AChunkAskedForTwiceIsGeneratedOnce) {
  const world::TerrainGenerator gen(7);
  TerrainPrefetcher p(gen, 1, 1000, 1000, {});
  const std::vector<ChunkCoord> want{{0, 0, 0}, {0, 1, 0}};
  p.request(want);
  p.request(want);
  const auto got = collect(p, 2);
  EXPECT_EQ(got.size(), 2u);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_TRUE(p.take_ready().empty()) << "no second copy";
}

TEST(TerrainPrefetcher, RefusesWhatIsOverItsBoundAndReservesMemoryForWhatIsOnItsWay) {
  const world::TerrainGenerator gen(7);
  std::mutex m;
  std::condition_variable cv;
  bool go = false;
  // The first notification blocks the (one) worker, so nothing more completes meanwhile.
  TerrainPrefetcher p(gen, 1, 3, 500, [&] {
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return go; });
  });
  const std::vector<ChunkCoord> want{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
  const std::vector<ChunkCoord> refused = p.request(want);
  EXPECT_EQ(refused, (std::vector<ChunkCoord>{{3, 0, 0}, {4, 0, 0}}))
      << "the caller generates these itself";
  EXPECT_EQ(p.pending_count(), 3u);
  EXPECT_GE(p.memory_bytes(), 2 * 500u) << "chunks on their way count at their reserve";
  {
    std::lock_guard lock(m);
    go = true;
  }
  cv.notify_all();
  EXPECT_EQ(collect(p, 3).size(), 3u);
  EXPECT_EQ(p.memory_bytes(), 0u);
}

TEST(TerrainPrefetcher, WithoutThreadsEverythingIsRefused) {
  const world::TerrainGenerator gen(7);
  TerrainPrefetcher p(gen, 0, 100, 1000, {});
  const std::vector<ChunkCoord> want{{0, 0, 0}};
  EXPECT_EQ(p.request(want), want);
  EXPECT_EQ(p.pending_count(), 0u);
}

}  // namespace
}  // namespace vox::pipeline
