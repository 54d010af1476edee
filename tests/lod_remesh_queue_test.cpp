// Re-meshing level-of-detail chunks after edits (server/pipeline/lod_remesh_queue.hpp):
// which chunks an edit reaches, coalescing to once per interval, the bound.
#include "server/pipeline/lod_remesh_queue.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;
using world::LodChunk;
using Clock = LodRemeshQueue::Clock;

const auto kEveryone = [](const LodChunk&) { return true; };

TEST(LodRemeshQueue, AnEditReachesTheChunksOfEveryLevelWhoseSamplesItChanged) {
  const LodRemeshQueue queue(7, 250ms, 1000);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int32_t> pos(-5000, 5000), size(0, 12);
  std::vector<LodChunk> got;
  for (int trial = 0; trial < 50; ++trial) {
    world::VoxelBox box;
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = pos(rng);
      box.hi[a] = box.lo[a] + size(rng);
    }
    queue.affected(box, got);
    // Brute force: chunk c of level k samples voxels [32s c - s, 32s c + 33s], s = 2^k.
    std::vector<LodChunk> want;
    for (int level = 1; level < 7; ++level) {
      const int64_t s = int64_t{1} << level, side = 32 * s;
      std::array<std::vector<int32_t>, 3> axis;
      for (int a = 0; a < 3; ++a) {
        const int64_t centre = box.lo[a] / side;
        for (int64_t c = centre - 3; c <= centre + 3; ++c)
          if (side * c - s <= box.hi[a] && side * c + 33 * s >= box.lo[a])
            axis[a].push_back(static_cast<int32_t>(c));
      }
      for (int32_t z : axis[2])
        for (int32_t y : axis[1])
          for (int32_t x : axis[0]) want.push_back({level, {x, y, z}});
    }
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    EXPECT_EQ(got, want);
  }
  // A voxel on a level-1 chunk's corner reaches the 8 chunks around it (their padding).
  queue.affected({{0, 0, 0}, {0, 0, 0}}, got);
  EXPECT_EQ(std::count_if(got.begin(), got.end(), [](const LodChunk& c) { return c.level == 1; }),
            8);
}

TEST(LodRemeshQueue, OnlyViewedChunksWaitAndForgottenOnesLeave) {
  LodRemeshQueue queue(4, 250ms, 1000);
  const Clock::time_point t0{};
  queue.mark({{10, 10, 10}, {10, 10, 10}}, t0, [](const LodChunk& c) { return c.level == 2; });
  ASSERT_EQ(queue.pending(), 1u);
  const auto taken = queue.take_due(t0, 10);
  ASSERT_EQ(taken.size(), 1u);
  EXPECT_EQ(taken[0], (LodChunk{2, {0, 0, 0}}));
  queue.mark({{10, 10, 10}, {10, 10, 10}}, t0, kEveryone);
  EXPECT_EQ(queue.pending(), 3u);
  queue.forget({1, {0, 0, 0}});
  EXPECT_EQ(queue.pending(), 2u);
}

// The storm: explosions every 10 ms for 3 s across a 300-voxel area, the pipeline
// taking what is due every 10 ms. No chunk is re-meshed twice within its level's interval,
// and every edit reaches every chunk it marked within that interval plus one pipeline tick.
TEST(LodRemeshQueue, AStormOfExplosionsReMeshesEachCoarseChunkAtMostOncePerInterval) {
  const auto interval = 250ms, tick = 10ms;
  LodRemeshQueue queue(7, interval, 100000);
  std::mt19937 rng(8);
  std::uniform_int_distribution<int32_t> pos(0, 300);
  std::map<LodChunk, std::vector<Clock::time_point>> taken;
  std::map<LodChunk, Clock::time_point> waiting_since;  // the first unserved mark
  Clock::duration worst_late{};                         // past the chunk's level's interval
  std::vector<LodChunk> marked;
  const Clock::time_point t0{};
  size_t marks = 0;
  for (Clock::time_point now = t0; now < t0 + 3s; now += tick) {
    const std::array<int32_t, 3> p{pos(rng), pos(rng) / 4, pos(rng)};
    const world::VoxelBox box{{p[0] - 6, p[1] - 6, p[2] - 6}, {p[0] + 6, p[1] + 6, p[2] + 6}};
    queue.mark(box, now, kEveryone);
    queue.affected(box, marked);
    marks += marked.size();
    for (const LodChunk& c : marked) waiting_since.try_emplace(c, now);
    for (const LodChunk& c : queue.take_due(now, 1000)) {
      taken[c].push_back(now);
      const auto it = waiting_since.find(c);
      ASSERT_NE(it, waiting_since.end());
      worst_late = std::max(worst_late, now - it->second - queue.interval(c.level));
      waiting_since.erase(it);
    }
  }
  size_t remeshes = 0;
  for (const auto& [c, times] : taken) {
    remeshes += times.size();
    for (size_t i = 1; i < times.size(); ++i)
      EXPECT_GE(times[i] - times[i - 1], queue.interval(c.level)) << "level " << c.level;
  }
  EXPECT_LE(worst_late, tick);
  EXPECT_LT(remeshes * 2, marks) << "marks coalesce (3,488 marks, 982 re-meshes)";
  EXPECT_GT(taken.size(), 20u);
  EXPECT_EQ(queue.dropped(), 0u);
}

// A coarse chunk covers many players' edits and goes to every viewer of it: level 1 is
// re-meshed at most once per interval, each coarser level half as often, down to 1/8. A
// chunk not re-meshed within its interval is due at once (a lone edit shows at once).
TEST(LodRemeshQueue, CoarserLevelsAreReMeshedLessOftenDownToAnEighth) {
  LodRemeshQueue queue(7, 250ms, 1000);
  EXPECT_EQ(queue.interval(1), 250ms);
  EXPECT_EQ(queue.interval(2), 500ms);
  EXPECT_EQ(queue.interval(3), 1000ms);
  EXPECT_EQ(queue.interval(4), 2000ms);
  EXPECT_EQ(queue.interval(6), 2000ms);
  const world::VoxelBox box{{10, 10, 10}, {10, 10, 10}};
  const Clock::time_point t0{};
  queue.mark(box, t0, kEveryone);
  std::set<int> levels;
  for (const LodChunk& c : queue.take_due(t0, 100)) levels.insert(c.level);
  EXPECT_EQ(levels, (std::set<int>{1, 2, 3, 4, 5, 6})) << "every level at once";
  queue.mark(box, t0 + 10ms, kEveryone);
  // Marked again 10 ms later: each level falls due at its own interval after the first take.
  const std::vector<std::pair<Clock::duration, std::set<int>>> schedule = {
      {250ms, {1}}, {500ms, {2}}, {1000ms, {3}}, {2000ms, {4, 5, 6}}};
  for (const auto& [at, want] : schedule) {
    EXPECT_TRUE(queue.take_due(t0 + at - 1ms, 100).empty()) << "before " << at.count();
    std::set<int> got;
    for (const LodChunk& c : queue.take_due(t0 + at, 100)) got.insert(c.level);
    EXPECT_EQ(got, want) << "at " << at.count();
  }
  EXPECT_EQ(queue.pending(), 0u);
}

TEST(LodRemeshQueue, PastItsBoundTheCoarsestChunksAreDroppedAndCounted) {
  LodRemeshQueue queue(7, 250ms, 20);
  const Clock::time_point t0{};
  for (int i = 0; i < 40; ++i)
    queue.mark({{i * 200, 0, 0}, {i * 200, 0, 0}}, t0, [](const LodChunk&) { return true; });
  EXPECT_EQ(queue.pending(), 20u);
  EXPECT_GT(queue.dropped(), 0u);
  const auto taken = queue.take_due(t0, 100);
  ASSERT_EQ(taken.size(), 20u);
  EXPECT_EQ(taken.front().level, 1) << "finest first; the coarsest were dropped";
  EXPECT_TRUE(
      std::all_of(taken.begin(), taken.end(), [](const LodChunk& c) { return c.level <= 2; }));
  EXPECT_FALSE(queue.next_due().has_value());
  EXPECT_EQ(queue.take_dropped().size(), queue.dropped()) << "the caller drops their meshes";
  EXPECT_TRUE(queue.take_dropped().empty());
}

// Under a steady stream of edits near the eye, a coarse chunk that fell due earlier is
// not passed over by finer ones marked after it (it was: finest first starved level 2+).
TEST(LodRemeshQueue, DueChunksAreTakenInTheOrderTheyFellDueSoNoLevelStarves) {
  LodRemeshQueue queue(4, 250ms, 1000);
  const Clock::time_point t0{std::chrono::seconds(10)};
  const auto coarse_only = [](const LodChunk& c) { return c.level == 3; };
  queue.mark({{5000, 0, 0}, {5000, 0, 0}}, t0, coarse_only);
  for (int i = 1; i <= 50; ++i)
    queue.mark({{i * 70, 0, 0}, {i * 70, 0, 0}}, t0 + i * 1ms,
               [](const LodChunk& c) { return c.level == 1; });
  const auto first = queue.take_due(t0 + 60ms, 1);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].level, 3);
}

}  // namespace
}  // namespace vox::pipeline
