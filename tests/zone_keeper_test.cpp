// A node's zone ownership rounds (server/cluster/zone_plan.hpp, zone_keeper.hpp) against a
// real PostgreSQL: every zone asked for gets exactly one owner, the node that ranks first;
// a crashed node's zones move within a lease, a stopped node's at once, and a node that
// joins takes over the zones it now ranks first for.
#include "server/cluster/zone_keeper.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include "server/cluster/zone_plan.hpp"
#include "server/store/zone_leases.hpp"
#include "tests/eventually.hpp"
#include "tests/postgres_server.hpp"

namespace vox::cluster {
namespace {

using std::chrono::milliseconds;
using namespace std::chrono_literals;
using test::eventually;
using world::ZoneId;

TEST(ZonePlan, RenewWhatItRanksFirstForHandOffTheRestTakeWhatItWasAskedFor) {
  const std::vector<std::string> live{"a", "b"};
  std::set<ZoneId> mine, theirs;
  for (int x = 0; x < 40; ++x) {
    const ZoneId z{x, 0};
    (live[*world::first_ranked(z, live)] == "a" ? mine : theirs).insert(z);
  }
  ASSERT_FALSE(mine.empty());
  ASSERT_FALSE(theirs.empty());
  // a alone held everything; b joined.
  std::set<ZoneId> all = mine;
  all.insert(theirs.begin(), theirs.end());
  const ZonePlan plan = plan_zones(all, {}, live, "a");
  EXPECT_EQ(std::set<ZoneId>(plan.renew.begin(), plan.renew.end()), mine);
  EXPECT_EQ(std::set<ZoneId>(plan.hand_off.begin(), plan.hand_off.end()), theirs);
  EXPECT_TRUE(plan.take.empty());
  // b is asked for everything and holds nothing: it takes its own.
  const ZonePlan b = plan_zones({}, all, live, "b");
  EXPECT_EQ(std::set<ZoneId>(b.take.begin(), b.take.end()), theirs);
  // A node missing from the live list (its heartbeat not in yet) still counts itself.
  EXPECT_EQ(plan_zones({}, all, {"b"}, "a").take.size(), mine.size());
}

class ZoneKeeperTest : public ::testing::Test {
 protected:
  static std::string fresh_database() { return test::fresh_shared_database("keeper"); }

  // What the callbacks saw, per node.
  struct Seen {
    std::mutex mutex;
    std::map<std::string, std::map<ZoneId, uint64_t>> taken, lost;
    ZoneKeeper::Events events(const std::string& node) {
      return {.taken =
                  [this, node](ZoneId z, uint64_t e) {
                    std::lock_guard lock(mutex);
                    taken[node][z] = e;
                  },
              .lost =
                  [this, node](ZoneId z, uint64_t e) {
                    std::lock_guard lock(mutex);
                    lost[node][z] = e;
                  }};
    }
  };
  std::unique_ptr<ZoneKeeper> keeper(const std::string& db, const std::string& node, Seen& seen,
                                     milliseconds lease = milliseconds(600)) {
    return std::make_unique<ZoneKeeper>(
        ZoneKeeper::Config{.uri = db, .node = node, .address = node + ":7777", .lease = lease},
        seen.events(node));
  }
  // Both asked for every zone; returns once they hold all of them between them.
  static void ask_both(ZoneKeeper& a, ZoneKeeper& b) {
    for (const ZoneId z : zones()) {
      a.want(z);
      b.want(z);
    }
    ASSERT_TRUE(eventually([&] { return a.held_count() + b.held_count() == zones().size(); }));
  }
  static std::vector<ZoneId> zones() {
    std::vector<ZoneId> out;
    for (int x = 0; x < 8; ++x) out.push_back({x, -x});
    return out;
  }
};

TEST_F(ZoneKeeperTest, EveryZoneAskedForGetsOneOwnerTheNodeThatRanksFirst) {
  const std::string db = fresh_database();
  Seen seen;
  auto a = keeper(db, "a", seen), b = keeper(db, "b", seen);
  ask_both(*a, *b);
  const std::vector<std::string> live{"a", "b"};
  // Both heartbeats are in after the first rounds: each zone ends with its first-ranked node.
  ASSERT_TRUE(eventually([&] {
    for (const ZoneId z : zones()) {
      const bool a_first = live[*world::first_ranked(z, live)] == "a";
      if (a->epoch_of(z).has_value() != a_first || b->epoch_of(z).has_value() == a_first)
        return false;
    }
    return true;
  }));
}

// kill -9 of a node: its leases run out and the other node takes its zones, with new
// epochs that fence anything the dead one might still try.
TEST_F(ZoneKeeperTest, ACrashedNodesZonesAreTakenByTheOtherOnceItsLeasesRunOut) {
  const std::string db = fresh_database();
  Seen seen;
  auto a = keeper(db, "a", seen), b = keeper(db, "b", seen);
  ask_both(*a, *b);
  ASSERT_TRUE(eventually([&] { return a->held_count() > 0 && b->held_count() > 0; }));
  std::map<ZoneId, uint64_t> a_held;
  for (const ZoneId z : zones())
    if (auto e = a->epoch_of(z)) a_held[z] = *e;
  const auto crashed = std::chrono::steady_clock::now();
  a->stop(false);  // no release: as if killed
  ASSERT_TRUE(eventually([&] { return b->held_count() == zones().size(); }));
  const auto moved = std::chrono::steady_clock::now() - crashed;
  // A lease (600 ms) and a round or two; generous for sanitizer builds on a busy machine.
  EXPECT_LT(moved, milliseconds(4000));
  store::ZoneLeases old_a(db, "a-probe", milliseconds(600));
  for (const auto& [z, epoch] : a_held) {
    EXPECT_GT(*b->epoch_of(z), epoch);
    EXPECT_THROW(old_a.append(z, epoch, std::vector<store::ZoneRecord>{{1, 0, {1}}}),
                 store::FencedError);
  }
}

TEST_F(ZoneKeeperTest, AStoppedNodeReleasesItsZonesAndTheOtherTakesThemInItsNextRound) {
  const std::string db = fresh_database();
  Seen seen;
  const milliseconds lease(6000);  // rounds every 2 s
  auto a = keeper(db, "a", seen, lease), b = keeper(db, "b", seen, lease);
  ask_both(*a, *b);
  ASSERT_TRUE(eventually([&] { return a->held_count() > 0; }));
  const auto stopped = std::chrono::steady_clock::now();
  a->stop(true);
  EXPECT_EQ(a->held_count(), 0u);
  {
    std::lock_guard lock(seen.mutex);  // every zone a took, it was told it lost
    for (const auto& [z, e] : seen.taken["a"]) EXPECT_TRUE(seen.lost["a"].contains(z));
  }
  // Released and out of the live list: b takes them in its next round, before a's lease
  // (6 s) or heartbeat would have run out.
  ASSERT_TRUE(eventually([&] { return b->held_count() == zones().size(); }, milliseconds(5000)));
  EXPECT_LT(std::chrono::steady_clock::now() - stopped, lease);
}

TEST_F(ZoneKeeperTest, ANodeThatJoinsTakesOverTheZonesItNowRanksFirstFor) {
  const std::string db = fresh_database();
  Seen seen;
  auto a = keeper(db, "a", seen);
  for (const ZoneId z : zones()) a->want(z);
  ASSERT_TRUE(eventually([&] { return a->held_count() == zones().size(); }));
  auto b = keeper(db, "b", seen);
  for (const ZoneId z : zones()) b->want(z);
  const std::vector<std::string> live{"a", "b"};
  size_t for_b = 0;
  for (const ZoneId z : zones()) for_b += live[*world::first_ranked(z, live)] == "b";
  ASSERT_GT(for_b, 0u);
  ASSERT_TRUE(eventually([&] { return b->held_count() == for_b; }));
  EXPECT_EQ(a->held_count(), zones().size() - for_b);
  std::lock_guard lock(seen.mutex);
  EXPECT_EQ(seen.lost["a"].size(), for_b);  // handed off, each told
}

// Two live processes given the same node id took the id's zones from each other in every
// round (each take by "a" took anew, fencing the other "a"): every zone's epoch climbed
// and edits were refused or waited a second. The second now holds nothing while the
// first lives, and takes the zones once the first is gone.
TEST_F(ZoneKeeperTest, TwoProcessesGivenOneNodeIdDoNotTakeZonesFromEachOther) {
  const std::string db = fresh_database();
  Seen seen, seen_twin;
  // Leases long enough that no renewal of a busy sanitizer build runs late.
  const milliseconds lease(2500);
  auto a = keeper(db, "a", seen, lease), b = keeper(db, "b", seen, lease);
  ask_both(*a, *b);
  const std::vector<std::string> live{"a", "b"};
  ASSERT_TRUE(eventually([&] {  // settled: each zone with its first-ranked node
    for (const ZoneId z : zones()) {
      const bool a_first = live[*world::first_ranked(z, live)] == "a";
      if (a->epoch_of(z).has_value() != a_first || b->epoch_of(z).has_value() == a_first)
        return false;
    }
    return true;
  }));
  auto twin = keeper(db, "a", seen_twin, lease);
  for (const ZoneId z : zones()) twin->want(z);
  std::map<ZoneId, uint64_t> epochs;
  for (const ZoneId z : zones()) {
    auto e = a->epoch_of(z);
    if (!e) e = b->epoch_of(z);
    epochs[z] = *e;
  }
  std::this_thread::sleep_for(milliseconds(3000));  // several rounds of all three
  EXPECT_EQ(twin->held_count(), 0u);
  {
    std::lock_guard lock(seen_twin.mutex);
    EXPECT_TRUE(seen_twin.taken["a"].empty()) << "the second process took a zone";
  }
  for (const ZoneId z : zones()) {
    auto e = a->epoch_of(z);
    if (!e) e = b->epoch_of(z);
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(*e, epochs[z]) << "zone " << z.x << "," << z.z << " was taken again";
  }
  const size_t a_held = a->held_count();
  a->stop(false);  // the first "a" dies: the twin's heartbeat takes the id, then a's zones
  ASSERT_TRUE(eventually([&] { return twin->held_count() == a_held; }, milliseconds(10000)));
}

// A zone newly viewed was followed only from the keeper's next round (a third of a
// lease): the first edit a player made there waited about 0.9 s with the default lease.
// A poke starts the round at once.
TEST_F(ZoneKeeperTest, APokeStartsARoundAtOnce) {
  const std::string db = fresh_database();
  Seen seen;
  std::atomic<int> rounds{0};
  ZoneKeeper::Events events = seen.events("a");
  events.round = [&](store::ZoneLeases&) { ++rounds; };
  ZoneKeeper k(ZoneKeeper::Config{.uri = db, .node = "a", .address = "a:1", .lease = 30s},
               std::move(events));
  ASSERT_TRUE(eventually([&] { return rounds.load() == 1; }));  // the first, at start
  k.poke();
  const auto poked = std::chrono::steady_clock::now();
  ASSERT_TRUE(eventually([&] { return rounds.load() == 2; }));
  EXPECT_LT(std::chrono::steady_clock::now() - poked, 5s);  // not the period's 10 s
}

TEST_F(ZoneKeeperTest, ZonesAskedForPastItsBoundAreRefused) {
  const std::string db = fresh_database();
  Seen seen;
  ZoneKeeper k(ZoneKeeper::Config{.uri = db, .node = "a", .address = "a:1", .max_zones = 3},
               seen.events("a"));
  EXPECT_TRUE(k.want({0, 0}));
  EXPECT_TRUE(k.want({0, 1}));
  EXPECT_TRUE(k.want({0, 2}));
  EXPECT_TRUE(k.want({0, 1}));   // already remembered
  EXPECT_FALSE(k.want({0, 3}));  // one too many
  ASSERT_TRUE(eventually([&] { return k.held_count() == 3; }));
  EXPECT_FALSE(k.epoch_of({0, 3}).has_value());
}

}  // namespace
}  // namespace vox::cluster
