// The pipeline's batching policy, rule by rule, including the adversarial cases that once
// made an edit wait a minute behind loads.
#include "server/pipeline/batch_scheduler.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "server/pipeline/memory_budget.hpp"
#include "server/pipeline/view_index.hpp"
#include "server/pipeline/world_pipeline.hpp"

namespace vox::pipeline {
namespace {

using world::ChunkCoord;

EditTask edit_tagged(int tag, std::vector<int>& log) {
  return EditTask{world::Brush{{0, 0, 0}, 1, 1, false, std::nullopt},
                  [tag, &log](const EditResult&) { log.push_back(tag); }};
}

size_t unit_cost(ChunkCoord) { return 1; }

// What the pipeline does per batch: every ordered task, then a load pass.
struct Taken {
  std::vector<OrderedTask> ordered;
  std::vector<LoadSlice> loads;
};
Taken next(BatchScheduler& s, size_t budget, const BatchScheduler::Cost& cost) {
  Taken t{s.take_ordered(), {}};
  t.loads = s.take_loads(budget, cost);
  return t;
}

std::vector<ChunkCoord> row(int owner_tag, int n) {
  std::vector<ChunkCoord> out;
  for (int i = 0; i < n; ++i) out.push_back({owner_tag, 0, i});
  return out;
}

TEST(BatchScheduler, EveryQueuedEditIsInTheNextBatchWhateverTheLoadBacklog) {
  BatchScheduler s(32);
  for (LoadOwner o = 1; o <= 20; ++o)
    s.request(o, row(static_cast<int>(o), 7153));  // 20 radius-12 views
  std::vector<int> log;
  for (int i = 0; i < 5000; ++i) s.add(edit_tagged(i, log));
  const Taken b = next(s, 64, unit_cost);
  ASSERT_EQ(b.ordered.size(), 5000u);
  for (size_t i = 0; i < b.ordered.size(); ++i) std::get<EditTask>(b.ordered[i]).done({});
  for (int i = 0; i < 5000; ++i) ASSERT_EQ(log[i], i) << "arrival order";
  size_t load_chunks = 0;
  for (const auto& slice : b.loads) load_chunks += slice.chunks.size();
  EXPECT_EQ(load_chunks, 64u) << "loads only fill the budget";
  EXPECT_FALSE(s.has_ordered());
}

TEST(BatchScheduler, EditsAndInspectionsKeepTheirArrivalOrder) {
  BatchScheduler s;
  std::vector<int> log;
  s.add(edit_tagged(1, log));
  s.add(InspectTask{[&log](bool) { log.push_back(2); }});
  s.add(edit_tagged(3, log));
  Taken b = next(s, 0, unit_cost);
  ASSERT_EQ(b.ordered.size(), 3u);
  std::get<EditTask>(b.ordered[0]).done({});
  std::get<InspectTask>(b.ordered[1]).run(false);
  std::get<EditTask>(b.ordered[2]).done({});
  EXPECT_EQ(log, (std::vector<int>{1, 2, 3}));
}

TEST(BatchScheduler, ABudgetOfZeroTakesNoLoads) {
  BatchScheduler s;
  s.request(1, row(1, 10));
  const Taken b = next(s, 0, unit_cost);
  EXPECT_TRUE(b.loads.empty());
  EXPECT_EQ(s.queued_load_chunks(), 10u);
}

TEST(BatchScheduler, ANewViewReplacesTheOwnersQueuedLoads) {
  BatchScheduler s;
  s.request(7, row(1, 1000));
  s.request(7, row(2, 1000));
  s.request(7, row(3, 5));  // the newest view wins
  EXPECT_EQ(s.queued_load_chunks(), 5u);
  EXPECT_EQ(s.load_owners(), 1u);
  const Taken b = next(s, 100, unit_cost);
  ASSERT_EQ(b.loads.size(), 1u);
  EXPECT_EQ(b.loads[0].chunks, row(3, 5));
  EXPECT_FALSE(s.has_loads());
}

TEST(BatchScheduler, ADroppedOwnerLeavesNoQueuedWork) {
  BatchScheduler s;
  for (LoadOwner o = 1; o <= 50; ++o) s.request(o, row(static_cast<int>(o), 7153));
  for (LoadOwner o = 1; o <= 50; ++o) s.drop(o);
  EXPECT_EQ(s.queued_load_chunks(), 0u);
  EXPECT_EQ(s.load_owners(), 0u);
  EXPECT_TRUE(next(s, 1000, unit_cost).loads.empty());
}

// A new player's small view is not delayed by a huge one queued before it: fewest chunks
// left first; and the huge one still moves (the round robin's part of the pass).
TEST(BatchScheduler, ASmallViewGoesBeforeAHugeOneWhichStillMoves) {
  BatchScheduler s(32);
  s.request(1, row(1, 7153));  // a huge view queued first
  s.request(2, row(2, 40));    // a new player's small view behind it
  const Taken b = next(s, 64, unit_cost);
  ASSERT_EQ(b.loads.size(), 2u) << "one slice per owner";
  EXPECT_EQ(b.loads[0].owner, 2u);
  EXPECT_EQ(b.loads[0].chunks.size(), 40u) << "the small view whole, in the first batch";
  EXPECT_EQ(b.loads[0].chunks.front(), (ChunkCoord{2, 0, 0})) << "its nearest chunk first";
  EXPECT_EQ(b.loads[1].owner, 1u);
  EXPECT_EQ(b.loads[1].chunks.size(), 24u) << "the rest of the budget";
  EXPECT_EQ(b.loads[1].chunks.front(), (ChunkCoord{1, 0, 0}));
  EXPECT_EQ(s.load_owners(), 1u);
}

// 200 players joining within seconds each waited for all of them: round robin moved every
// view a little each batch, so all finished together at the end. Of two alike views the
// one served longer (fewer chunks left) now goes first and finishes first.
TEST(BatchScheduler, OfTwoAlikeViewsTheOneServedLongerFinishesFirst) {
  BatchScheduler s(8);
  bool first_done = false, second_done = false;
  size_t second_taken_when_first_done = 0, second_taken = 0;
  s.request(1, row(1, 100), [&] { first_done = true; });
  s.request(2, row(2, 100), [&] { second_done = true; });
  for (int batch = 0; batch < 20 && !second_done; ++batch) {
    for (LoadSlice& slice : next(s, 40, unit_cost).loads) {
      if (slice.owner == 2) second_taken += slice.chunks.size();
      if (slice.done) slice.done();
      if (first_done && second_taken_when_first_done == 0)
        second_taken_when_first_done = second_taken;
    }
  }
  ASSERT_TRUE(first_done && second_done);
  EXPECT_LE(second_taken_when_first_done, 30u)
      << "round robin would have had both about 90 % done when the first finished";
}

TEST(BatchScheduler, ChunksWithNothingToDoCostNoTurnAndNoBudget) {
  BatchScheduler s(4);
  s.request(1, row(1, 100));
  // Only every tenth chunk needs work (a view that moved by one chunk).
  auto cost = [](ChunkCoord c) { return c.z % 10 == 0 ? size_t{5} : size_t{0}; };
  const Taken b = next(s, 20, cost);
  ASSERT_EQ(b.loads.size(), 1u);
  EXPECT_EQ(b.loads[0].chunks,
            (std::vector<ChunkCoord>{{1, 0, 0}, {1, 0, 10}, {1, 0, 20}, {1, 0, 30}}));
}

TEST(BatchScheduler, DoneRunsWithTheLastSliceOrIsHandedBackWhenReplaced) {
  BatchScheduler s(8);
  int finished = 0;
  s.request(1, row(1, 10), [&] { ++finished; });
  Taken b = next(s, 8, unit_cost);
  ASSERT_EQ(b.loads.size(), 1u);
  EXPECT_FALSE(b.loads[0].done);
  b = next(s, 8, unit_cost);
  ASSERT_TRUE(b.loads[0].done);
  b.loads[0].done();
  EXPECT_EQ(finished, 1);
  s.request(2, row(2, 10), [&] { finished += 10; });
  auto replaced = s.request(2, row(2, 3));
  ASSERT_TRUE(replaced);
  replaced();
  EXPECT_EQ(finished, 11);
}

TEST(BatchScheduler, ARequestWhoseChunksAllExistFinishesAtOnce) {
  BatchScheduler s;
  bool done = false;
  s.request(1, row(1, 500), [&] { done = true; });
  Taken b = next(s, 10, [](ChunkCoord) { return size_t{0}; });
  ASSERT_EQ(b.loads.size(), 1u);
  EXPECT_TRUE(b.loads[0].chunks.empty());
  b.loads[0].done();
  EXPECT_TRUE(done);
  EXPECT_FALSE(s.has_loads());
}

TEST(BatchScheduler, AnOwnerOverItsLoadBudgetWaitsWhileOthersGoOn) {
  using namespace std::chrono_literals;
  BatchScheduler s(32, /*owner_rate=*/100, /*owner_burst=*/64);
  const auto t0 = BatchScheduler::Clock::now();
  s.request(1, row(1, 7153));                                    // a flooder's view
  s.request(2, row(2, 200));                                     // a player's
  s.request(BatchScheduler::kUnlimitedOwners | 1, row(3, 200));  // a one-off load: never budgeted
  std::map<LoadOwner, size_t> by_owner;
  for (int batch = 0; batch < 10; ++batch) {
    for (const auto& slice : s.take_loads(1000, unit_cost, SIZE_MAX, t0)) {
      by_owner[slice.owner] += slice.chunks.size();
    }
  }
  EXPECT_LE(by_owner[1], 64u + 32u) << "the burst (and at most one group of debt)";
  EXPECT_LE(by_owner[2], 64u + 32u);
  EXPECT_EQ(by_owner[BatchScheduler::kUnlimitedOwners | 1], 200u)
      << "one-off loads are not budgeted";
  EXPECT_FALSE(s.has_ready_loads(t0));
  EXPECT_TRUE(s.has_ready_loads(t0 + 2s)) << "the budget refills";
  const auto later = s.take_loads(1000, unit_cost, SIZE_MAX, t0 + 2s);
  ASSERT_FALSE(later.empty());
}

// A view flooder that disconnected and reconnected got a fresh burst every time: 3
// flooders generated 62,000 chunks in 70 s instead of what their budgets allow.
TEST(BatchScheduler, ReconnectingFromTheSameAddressDoesNotRefillTheLoadBudget) {
  using namespace std::chrono_literals;
  BatchScheduler s(32, /*owner_rate=*/100, /*owner_burst=*/64, /*group_rate=*/100,
                   /*group_burst=*/96);
  const auto t0 = BatchScheduler::Clock::now();
  constexpr uint64_t kAddress = 42, kOther = 43;
  size_t taken = 0;
  for (LoadOwner session = 1; session <= 5; ++session) {  // connect, load, disconnect
    s.request(session, row(1, 1000), {}, kAddress);
    for (const auto& slice : s.take_loads(1000, unit_cost, SIZE_MAX, t0))
      taken += slice.chunks.size();
    s.drop(session, t0);
  }
  EXPECT_LE(taken, 96u + 32u) << "the address's burst (and at most one group of debt)";
  EXPECT_EQ(s.budget_groups(), 1u) << "an address in debt is remembered after its sessions left";
  s.request(9, row(9, 1000), {}, kOther);  // another address is not held back
  EXPECT_EQ(s.take_loads(1000, unit_cost, SIZE_MAX, t0).at(0).chunks.size(), 64u)
      << "its session's whole burst";
  s.drop(9, t0 + 10s);  // both refilled by then: nothing left to remember
  EXPECT_EQ(s.budget_groups(), 0u);
}

TEST(BatchScheduler, SessionsFromOneAddressShareItsBudgetAndKeepTheirOwn) {
  BatchScheduler s(8, /*owner_rate=*/100, /*owner_burst=*/16, /*group_rate=*/100,
                   /*group_burst=*/40);
  const auto t0 = BatchScheduler::Clock::now();
  for (LoadOwner session = 1; session <= 4; ++session)
    s.request(session, row(static_cast<int>(session), 100), {}, 7);
  std::map<LoadOwner, size_t> by_owner;
  for (int pass = 0; pass < 20; ++pass) {
    for (const auto& slice : s.take_loads(1000, unit_cost, SIZE_MAX, t0))
      by_owner[slice.owner] += slice.chunks.size();
  }
  size_t total = 0;
  for (const auto& [owner, n] : by_owner) {
    EXPECT_LE(n, 16u) << "each session within its own burst";
    total += n;
  }
  EXPECT_LE(total, 40u + 8u) << "all of them within the address's";
  EXPECT_GE(total, 40u);
}

TEST(BatchScheduler, APassConsidersAtMostTheScanLimit) {
  BatchScheduler s(32);
  for (LoadOwner o = 1; o <= 10; ++o) s.request(o, row(static_cast<int>(o), 7153));
  size_t considered = 0;
  const auto loads = s.take_loads(
      1000,
      [&](ChunkCoord) {
        ++considered;
        return size_t{0};
      },
      5000);
  EXPECT_EQ(considered, 5000u) << "fully meshed views are not scanned whole under the lock";
  EXPECT_TRUE(loads.empty());
  EXPECT_EQ(s.queued_load_chunks(), 10 * 7153u - 5000);
}

TEST(BatchScheduler, BallIsNearestFirstAndHoldsExactlyTheViewSphere) {
  const auto ball = ball_nearest_first({5, -3, 2}, 4);
  EXPECT_EQ(ball.front(), (ChunkCoord{5, -3, 2}));
  int64_t last = -1;
  std::set<ChunkCoord> unique(ball.begin(), ball.end());
  EXPECT_EQ(unique.size(), ball.size());
  for (const ChunkCoord& c : ball) {
    const int64_t dx = c.x - 5, dy = c.y + 3, dz = c.z - 2, d = dx * dx + dy * dy + dz * dz;
    EXPECT_LE(d, 16);
    EXPECT_GE(d, last);
    last = d;
  }
  EXPECT_EQ(ball.size(), 257u);  // chunks within radius 4
}

TEST(MemoryBudget, EvictsAboveNinetyPercentDownToEighty) {
  const MemoryBudget b(1000 * 1000);
  EXPECT_FALSE(b.should_evict(900 * 1000));
  EXPECT_TRUE(b.should_evict(900 * 1000 + 1));
  EXPECT_EQ(b.evict_target(100 * 1000), 700u * 1000);
  EXPECT_EQ(b.evict_target(2000 * 1000), 0u);
}

TEST(MemoryBudget, LoadsStopAtTheBudgetAndAPassCannotOvershootTenPercent) {
  const size_t max = 100u << 20;
  const MemoryBudget b(max);
  EXPECT_EQ(b.load_work(max, 2048), 0u);
  EXPECT_EQ(b.load_work(max + 5, 2048), 0u);
  EXPECT_EQ(b.load_work(0, 2048), 2048u);
  const size_t near = max - 1;
  const size_t work = b.load_work(near, 2048);
  EXPECT_GT(work, 0u);
  EXPECT_LE(near + work * MemoryBudget::kBytesPerLoadWork, max + max / 10);
  EXPECT_FALSE(b.may_generate(max, 0));
  EXPECT_TRUE(b.may_generate(max - 1, 0));
  EXPECT_TRUE(b.may_generate(max / 2, 100));
  EXPECT_FALSE(b.may_generate(max - (1 << 20), 300)) << "300 chunks could take 28 MiB";
}

TEST(MemoryBudget, NoBudgetMeansNoLimit) {
  const MemoryBudget b;
  EXPECT_FALSE(b.should_evict(SIZE_MAX / 2));
  EXPECT_EQ(b.load_work(SIZE_MAX / 2, 77), 77u);
  EXPECT_TRUE(b.may_generate(SIZE_MAX / 2, 1000));
}

}  // namespace
}  // namespace vox::pipeline

namespace vox::pipeline {
namespace {

TEST(ViewIndex, KnowsExactlyTheChunksInSomeonesViewAcrossRegions) {
  ViewIndex v;
  v.set(1, {15, 0, 0}, 3);  // straddles two regions on x
  EXPECT_TRUE(v.viewed({15, 0, 0}));
  EXPECT_TRUE(v.viewed({18, 0, 0}));
  EXPECT_TRUE(v.viewed({12, 0, 0}));
  EXPECT_FALSE(v.viewed({19, 0, 0}));
  EXPECT_FALSE(v.viewed({17, 2, 2})) << "outside the ball, inside its box";
  v.set(2, {-40, 5, -40}, 1);
  EXPECT_TRUE(v.viewed({-40, 6, -40}));
  v.set(1, {100, 0, 0}, 2);  // moved: the old place is no longer viewed
  EXPECT_FALSE(v.viewed({15, 0, 0}));
  EXPECT_TRUE(v.viewed({101, 1, 0}));
  v.remove(2);
  EXPECT_FALSE(v.viewed({-40, 5, -40}));
  EXPECT_EQ(v.size(), 1u);
}

}  // namespace
}  // namespace vox::pipeline
