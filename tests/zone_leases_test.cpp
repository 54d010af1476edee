// Zones (server/world/zone.hpp) and their leases, fences and logs in a real PostgreSQL
// (server/store/zone_leases.hpp).
#include "server/store/zone_leases.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <climits>
#include <functional>
#include <map>
#include <pqxx/pqxx>
#include <set>
#include <thread>

#include "tests/postgres_server.hpp"

namespace vox::store {
namespace {

using std::chrono::milliseconds;
using world::ZoneId;

TEST(Zone, ChunksMapToColumnsOfSizeChunksRoundedDown) {
  EXPECT_EQ(world::zone_of({0, 0, 0}, 16), (ZoneId{0, 0}));
  EXPECT_EQ(world::zone_of({15, -900, 15}, 16), (ZoneId{0, 0}));  // all heights
  EXPECT_EQ(world::zone_of({16, 0, -1}, 16), (ZoneId{1, -1}));
  EXPECT_EQ(world::zone_of({-16, 0, -17}, 16), (ZoneId{-1, -2}));
  for (const ZoneId z : {ZoneId{0, 0}, ZoneId{-1, 5}, ZoneId{INT32_MIN, INT32_MAX}})
    EXPECT_EQ(ZoneId::from_key(z.key()), z);
  EXPECT_THROW(world::zone_of({0, 0, 0}, 0), std::invalid_argument);
}

TEST(Zone, ABoxAcrossACornerTouchesTheFourZonesAround) {
  // Zones of 2 chunks = 64 voxels: a box around the corner (64, y, 64).
  const auto zones = world::zones_of({{60, -5, 60}, {70, 5, 70}}, 2);
  EXPECT_EQ(zones, (std::vector<ZoneId>{{0, 0}, {0, 1}, {1, 0}, {1, 1}}));
  EXPECT_EQ(world::zones_of({{1, 1, 1}, {2, 2, 2}}, 16), (std::vector<ZoneId>{{0, 0}}));
}

// A part of an edit logged in one zone keeps every sample outside it: the parts of a box
// outside the zone, with the part inside, cover the box exactly once.
TEST(Zone, ABoxOutsideItsZoneIsSplitIntoPartsThatCoverItExactlyOnce) {
  const world::VoxelBox box{{58, -5, 60}, {70, 5, 66}};  // zones of 64 voxels: four of them
  for (const ZoneId zone : world::zones_of(box, 2)) {
    const std::vector<world::VoxelBox> outside = world::outside_zone(box, zone, 2);
    for (int32_t x = box.lo[0]; x <= box.hi[0]; ++x) {
      for (int32_t z = box.lo[2]; z <= box.hi[2]; ++z) {
        int covered = 0;
        for (const auto& b : outside)
          covered += x >= b.lo[0] && x <= b.hi[0] && z >= b.lo[2] && z <= b.hi[2] &&
                     b.lo[1] == box.lo[1] && b.hi[1] == box.hi[1];
        const bool inside = world::zone_of(world::chunk_of_voxel(x, 0, z), 2) == zone;
        EXPECT_EQ(covered, inside ? 0 : 1) << x << ", " << z;
      }
    }
  }
  EXPECT_TRUE(world::outside_zone({{1, 1, 1}, {9, 9, 9}}, {0, 0}, 2).empty());
  // At the ends of the coordinates nothing overflows.
  const world::VoxelBox far{{INT32_MAX - 10, 0, INT32_MIN}, {INT32_MAX, 0, INT32_MIN + 10}};
  const ZoneId last = world::zones_of(far, 1).front();
  EXPECT_TRUE(world::outside_zone(far, last, 1).empty());
}

TEST(Zone, RendezvousMovesOnlyTheZonesOfANodeThatLeaves) {
  const std::vector<std::string> three{"node-a", "node-b", "node-c"};
  const std::vector<std::string> two{"node-a", "node-c"};
  std::map<std::string, int> owned;
  int moved = 0;
  for (int x = -20; x < 20; ++x)
    for (int z = -20; z < 20; ++z) {
      const ZoneId zone{x, z};
      const std::string before = three[*world::first_ranked(zone, three)];
      const std::string after = two[*world::first_ranked(zone, two)];
      ++owned[before];
      if (before != after) {
        EXPECT_EQ(before, "node-b") << "a zone of a node that stayed moved";
        ++moved;
      }
    }
  EXPECT_EQ(moved, owned["node-b"]);
  for (const auto& [node, count] : owned) EXPECT_GT(count, 1600 / 3 - 120) << node;  // spread
  // The same weights everywhere: a fixed hash, not the library's.
  EXPECT_EQ(world::rendezvous_weight({1, 2}, "node-a"), world::rendezvous_weight({1, 2}, "node-a"));
  EXPECT_NE(world::rendezvous_weight({1, 2}, "node-a"), world::rendezvous_weight({2, 1}, "node-a"));
  EXPECT_FALSE(world::first_ranked({0, 0}, {}).has_value());
}

// A fresh database per test on one PostgreSQL server for the program.
class ZoneLeasesTest : public ::testing::Test {
 protected:
  static std::string fresh_database() { return test::fresh_shared_database("zones"); }
  static std::vector<ZoneRecord> records(uint64_t first, int count) {
    std::vector<ZoneRecord> out;
    for (int i = 0; i < count; ++i)
      out.push_back({first + i, 1000 + i, {static_cast<uint8_t>(first + i), 7}});
    return out;
  }
  // `a` (a 300 ms lease) takes `zone`, appends records 1 .. n, does `then`, and is
  // "paused" past its lease; its epoch.
  static uint64_t hold_then_pause(ZoneLeases& a, ZoneId zone, int n,
                                  const std::function<void(uint64_t)>& then = {}) {
    const uint64_t epoch = *a.acquire(zone);
    a.append(zone, epoch, records(1, n));
    if (then) then(epoch);
    std::this_thread::sleep_for(milliseconds(400));
    return epoch;
  }
};

TEST_F(ZoneLeasesTest, ASecondNodeCannotTakeAZoneWhileTheFirstHoldsItsLease) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000)), b(db, "b", milliseconds(30000));
  const auto epoch = a.acquire({3, 4});
  ASSERT_EQ(epoch, 1u);
  EXPECT_FALSE(b.acquire({3, 4}).has_value());
  EXPECT_TRUE(a.renew({3, 4}, *epoch));
  EXPECT_FALSE(b.renew({3, 4}, *epoch));  // not b's
  const auto row = b.read({3, 4});
  ASSERT_TRUE(row);
  EXPECT_EQ(row->owner, "a");
  EXPECT_GT(row->lease_left_ms, 20000);
  EXPECT_EQ(b.acquire({3, 5}), 1u);  // another zone is free
}

// The safety rule: an owner paused past its lease (SIGSTOP, a VM stall) whose zone
// another node took can never write after its successor.
TEST_F(ZoneLeasesTest, AnOwnerPausedPastItsLeaseIsFencedOnceTheZoneIsTaken) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(300)), b(db, "b", milliseconds(300));
  const ZoneId zone{0, 0};
  const uint64_t first = hold_then_pause(a, zone, 3);
  const auto second = b.acquire(zone);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(*second, first + 1);
  // b reads what a committed, then writes after it.
  EXPECT_EQ(b.read_log(zone, 0).size(), 3u);
  b.append(zone, *second, records(4, 1));
  // a wakes up: its renewal and its writes are refused, and counted.
  EXPECT_FALSE(a.renew(zone, first));
  EXPECT_THROW(a.append(zone, first, records(5, 1)), FencedError);
  EXPECT_EQ(a.fenced(), 1u);
  EXPECT_EQ(b.fenced(), 0u);
  const auto log = b.read_log(zone, 0);
  ASSERT_EQ(log.size(), 4u);
  for (size_t i = 0; i < log.size(); ++i) EXPECT_EQ(log[i].seq, i + 1);
  EXPECT_EQ(log[3].payload, records(4, 1)[0].payload);  // b's, not a's
}

TEST_F(ZoneLeasesTest, AnAppendMustContinueTheZonesSequenceWithoutAGap) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  const ZoneId zone{-2, 9};
  const uint64_t epoch = *a.acquire(zone);
  a.append(zone, epoch, records(1, 2));
  EXPECT_THROW(a.append(zone, epoch, records(2, 1)), StoreError);  // a record again
  EXPECT_THROW(a.append(zone, epoch, records(4, 1)), StoreError);  // a gap
  std::vector<ZoneRecord> holed = records(3, 3);
  holed.erase(holed.begin() + 1);
  EXPECT_THROW(a.append(zone, epoch, holed), StoreError);
  a.append(zone, epoch, records(3, 2));
  EXPECT_EQ(a.read({-2, 9})->last_seq, 4u);
  EXPECT_EQ(a.read_log(zone, 2).size(), 2u);
  EXPECT_EQ(a.fenced(), 0u);  // refused for the sequence, not the fence
}

// A batch of edits across zones lands in every zone's log or in none: one zone fenced
// refuses the whole append, and the other zone's sequence is left as it was.
TEST_F(ZoneLeasesTest, AnAppendAcrossZonesLandsWholeOrNotAtAll) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(300)), b(db, "b", milliseconds(30000));
  const ZoneId one{0, 0}, two{0, 1};
  const uint64_t e1 = *a.acquire(one), e2 = *a.acquire(two);
  const auto r1 = records(1, 2), r2 = records(1, 3);
  a.append(std::vector<ZoneAppend>{{two, e2, r2}, {one, e1, r1}});
  EXPECT_EQ(a.read(one)->last_seq, 2u);
  EXPECT_EQ(a.read(two)->last_seq, 3u);
  std::this_thread::sleep_for(milliseconds(400));  // a's leases run out; b takes zone two
  ASSERT_TRUE(b.acquire(two).has_value());
  const auto more1 = records(3, 1), more2 = records(4, 1);
  try {
    a.append(std::vector<ZoneAppend>{{one, e1, more1}, {two, e2, more2}});
    ADD_FAILURE() << "a fenced zone's append landed";
  } catch (const FencedError& e) {
    EXPECT_EQ(e.zone, two);
  }
  EXPECT_EQ(a.read(one)->last_seq, 2u);  // zone one's part did not land either
  EXPECT_EQ(a.read_log(one, 0).size(), 2u);
  EXPECT_THROW(a.append(std::vector<ZoneAppend>{{one, e1, more1}, {one, e1, more1}}),
               StoreError);  // one zone twice
}

TEST_F(ZoneLeasesTest, TheFirstNodeSettlesTheWorldsSettingsAndTheOthersReadThem) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000)), b(db, "b", milliseconds(30000));
  const WorldSettings first{"main", 7, 16};
  EXPECT_EQ(a.settle_world(first), first);
  EXPECT_EQ(b.settle_world({"other", 8, 4}), first);  // the caller refuses to start
}

// Protected regions in a cluster (docs/CLUSTER.md, "Protected regions"): one table,
// versioned; a change bumps the version in its append's transaction, an append whose edits
// were clipped by an older table is refused and writes nothing (no zone is lost), and of
// two changes made at the same version the second is refused.
TEST_F(ZoneLeasesTest, AnAppendClippedByAnOlderRegionTableIsRefusedAndWritesNothing) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000)), b(db, "b", milliseconds(30000));
  a.settle_world({"main", 7, 16});
  EXPECT_EQ(b.read_regions().version, 0u);
  const ZoneId one{0, 0}, two{1, 0};
  const uint64_t e1 = *a.acquire(one), e2 = *b.acquire(two);
  world::Region keep;
  keep.id = 1;
  keep.name = "spawn";
  keep.box = {{0, -10, 0}, {20, 10, 20}};
  keep.owners = {"builder"};
  keep.created_by = "admin";
  const RegionWrite add{.whole = false, .upsert = {keep}, .remove = {}, .next_id = 2};
  const RegionsAt with_add{0, &add};
  const auto r1 = records(1, 1);
  EXPECT_EQ(a.append(std::vector<ZoneAppend>{{one, e1, r1}}, &with_add), 1u);
  const ZoneRegions seen = b.read_regions();
  EXPECT_EQ(seen.version, 1u);
  ASSERT_EQ(seen.table.regions.size(), 1u);
  EXPECT_EQ(seen.table.regions[0].name, "spawn");
  EXPECT_EQ(seen.table.regions[0].owners, std::vector<std::string>{"builder"});
  EXPECT_EQ(seen.table.next_id, 2u);
  // b's edits were clipped by the table before: refused, nothing written, nothing fenced.
  const RegionsAt stale{0, nullptr}, current{1, nullptr};
  try {
    b.append(std::vector<ZoneAppend>{{two, e2, r1}}, &stale);
    ADD_FAILURE() << "an append clipped by an older table landed";
  } catch (const RegionsChangedError& e) {
    EXPECT_EQ(e.version, 1u);
  }
  EXPECT_EQ(b.read(two)->last_seq, 0u);
  EXPECT_EQ(b.fenced(), 0u);
  EXPECT_EQ(b.append(std::vector<ZoneAppend>{{two, e2, r1}}, &current), 1u);
  EXPECT_EQ(b.read(two)->last_seq, 1u);
  // Two changes made at version 1: the first lands (alone, no records), the second not.
  const RegionWrite remove{.whole = false, .upsert = {}, .remove = {1}, .next_id = 2};
  world::Region other = keep;
  other.id = 2;
  const RegionWrite add_other{.whole = false, .upsert = {other}, .remove = {}, .next_id = 3};
  const RegionsAt first{1, &remove}, second{1, &add_other};
  EXPECT_EQ(a.append({}, &first), 2u);
  EXPECT_THROW(b.append({}, &second), RegionsChangedError);
  const ZoneRegions after = a.read_regions();
  EXPECT_EQ(after.version, 2u);
  EXPECT_TRUE(after.table.regions.empty());
  EXPECT_EQ(after.table.next_id, 2u);  // ids are never given again
  EXPECT_EQ(b.regions_version(), 2u);
  // A migration seeds an empty table only.
  a.seed_regions({.regions = {keep, other}, .next_id = 5});
  EXPECT_EQ(a.read_regions().table.regions.size(), 2u);
  EXPECT_EQ(a.read_regions().table.next_id, 5u);
  EXPECT_THROW(a.seed_regions({.regions = {keep}, .next_id = 5}), StoreError);
}

TEST_F(ZoneLeasesTest, AReleasedZoneIsTakenAtOnceAndARestartedNodeFencesItsEarlierRun) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000)), b(db, "b", milliseconds(30000));
  const ZoneId zone{1, 1};
  const uint64_t first = *a.acquire(zone);
  a.release(zone, first);
  EXPECT_FALSE(a.renew(zone, first));
  const auto taken = b.acquire(zone);
  ASSERT_TRUE(taken);
  EXPECT_EQ(*taken, first + 1);
  // b restarts under the same id and takes the zone again: a new epoch, so its earlier
  // run (perhaps only paused) is fenced.
  ZoneLeases b_again(db, "b", milliseconds(30000));
  const auto again = b_again.acquire(zone);
  ASSERT_TRUE(again);
  EXPECT_EQ(*again, *taken + 1);
  EXPECT_THROW(b.append(zone, *taken, records(1, 1)), FencedError);
  b_again.append(zone, *again, records(1, 1));
}

TEST_F(ZoneLeasesTest, OfNodesRacingForAFreeZoneExactlyOneTakesIt) {
  const std::string db = fresh_database();
  constexpr int kNodes = 6;
  std::vector<std::unique_ptr<ZoneLeases>> nodes;
  for (int i = 0; i < kNodes; ++i)
    nodes.push_back(std::make_unique<ZoneLeases>(db, "n" + std::to_string(i), milliseconds(30000)));
  std::atomic<int> takers{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < kNodes; ++i) {
    threads.emplace_back([&, i] {
      if (nodes[i]->acquire({7, 7})) takers.fetch_add(1);
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(takers.load(), 1);
  EXPECT_EQ(nodes[0]->read({7, 7})->epoch, 1u);
}

// Edits across zones held by different nodes (docs/CLUSTER.md): a part logged in one zone
// leaves the others pending unless their logs have them; a pending part goes when its
// zone's log gets it; read_pending shows only old enough rows, and drops stale ones.
TEST_F(ZoneLeasesTest, APartLoggedInOneZoneLeavesTheOthersPendingUntilTheirLogsHaveThem) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000)), b(db, "b", milliseconds(30000));
  const ZoneId za{0, 0}, zb{1, 0}, zc{1, 1};
  const uint64_t ea = *a.acquire(za), eb = *b.acquire(zb);
  // Edit 41 across za, zb and zc: a logs its part first; zb's and zc's are pending.
  std::vector<ZoneRecord> part_a = {{1, 500, {1, 41}, 41}};
  std::vector<ZonePending> others = {{zb, 41, 500, {2, 41}}, {zc, 41, 500, {3, 41}}};
  a.append(std::vector<ZoneAppend>{{za, ea, part_a, others}});
  const std::vector<ZoneId> mine = {zb, zc};
  EXPECT_TRUE(b.read_pending(mine, milliseconds(60000)).empty()) << "too young to be shown";
  std::vector<ZonePending> pending = b.read_pending(mine, milliseconds(0));
  ASSERT_EQ(pending.size(), 2u);
  EXPECT_EQ(pending[0].edit_id, 41u);
  EXPECT_EQ(pending[0].unix_ms, 500);
  // b logs zb's part (its own request came): zb's pending part goes in that transaction.
  std::vector<ZoneRecord> part_b = {{1, 500, {2, 41}, 41}};
  std::vector<ZonePending> others_b = {{za, 41, 500, {1, 41}}, {zc, 41, 500, {3, 41}}};
  b.append(std::vector<ZoneAppend>{{zb, eb, part_b, others_b}});
  pending = b.read_pending(mine, milliseconds(0));
  ASSERT_EQ(pending.size(), 1u) << "za's log has the edit: no part of it pending for za";
  EXPECT_EQ(pending[0].zone, zc);
  EXPECT_EQ(pending[0].payload, (std::vector<uint8_t>{3, 41}));
  EXPECT_TRUE(a.read_pending(std::vector<ZoneId>{za}, milliseconds(0)).empty());
  // The log keeps each record's edit id.
  const auto log = a.read_log(zb, 0);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0].edit_id, 41u);
  // zc's holder completes it: nothing is left.
  const uint64_t ec = *b.acquire(zc);
  b.append(std::vector<ZoneAppend>{{zc, ec, std::vector<ZoneRecord>{{1, 500, {3, 41}, 41}}, {}}});
  EXPECT_TRUE(b.read_pending(mine, milliseconds(0)).empty());
}

// A node stopped (SIGSTOP, a VM pause) inside a transaction keeps its zone row locked:
// another node's round must not wait on it longer than a fraction of a lease (it fails and
// retries), and the server ends the stalled transaction after a lease.
TEST_F(ZoneLeasesTest, ANodeStalledHoldingAZoneRowsLockDoesNotStallAnothersRound) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(300)), b(db, "b", milliseconds(1000));
  const ZoneId zone{0, 0};  // its row's key is 0
  ASSERT_TRUE(a.acquire(zone));
  std::this_thread::sleep_for(milliseconds(400));  // a's lease has run out
  std::thread stalled([&] {                        // a writer holding the row's lock for 3 s
    const std::string cmd = "psql '" + db +
                            "' -q -c 'BEGIN; SELECT 1 FROM zones WHERE zone = 0 FOR UPDATE; "
                            "SELECT pg_sleep(3); COMMIT;' > /dev/null 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0);
  });
  std::this_thread::sleep_for(milliseconds(700));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(b.acquire(zone), StoreError);
  EXPECT_LT(std::chrono::steady_clock::now() - start, milliseconds(1500))
      << "a round waited on the stalled writer's lock";
  stalled.join();
  EXPECT_TRUE(b.acquire(zone).has_value()) << "taken once the lock is gone";
}

// Two holders committing parts of one edit at once may each miss the other's (neither
// transaction sees the other's rows): a pending row is left for a zone whose log has the
// edit. read_pending drops it rather than have it applied twice.
TEST_F(ZoneLeasesTest, AStalePendingPartWhoseZoneLogHasTheEditIsDropped) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  const ZoneId za{0, 0};
  const uint64_t ea = *a.acquire(za);
  a.append(std::vector<ZoneAppend>{{za, ea, std::vector<ZoneRecord>{{1, 500, {1, 77}, 77}}, {}}});
  // The row the race leaves (za's key is 0), written as a concurrent writer would have.
  const std::string cmd = "psql '" + db +
                          "' -q -c \"INSERT INTO zone_pending (zone, edit_id, at_ms, record) " +
                          "VALUES (0, 77, 500, '\\\\x0177')\" > /dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_TRUE(a.read_pending(std::vector<ZoneId>{za}, milliseconds(0)).empty())
      << "a stale pending part would be applied again";
  a.append(std::vector<ZoneAppend>{{za, ea, std::vector<ZoneRecord>{{2, 501, {2}, 78}}, {}}});
  EXPECT_EQ(a.read_log(za, 0).size(), 2u);
}

// Zone checkpoints (docs/CLUSTER.md): a reader gets every chunk in its latest version
// through the zone's checkpoint_seq, and the edit ids of the records before it.
TEST_F(ZoneLeasesTest, AZoneCheckpointIsReadAsEachChunksLatestVersionThroughIt) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  const ZoneId zone{1, -1};
  EXPECT_FALSE(a.read_checkpoint(zone, 10).has_value());  // no zone row yet
  const uint64_t epoch = *a.acquire(zone);
  std::vector<ZoneRecord> log = records(1, 6);
  for (size_t i = 0; i < log.size(); ++i) log[i].edit_id = 100 + i;
  a.append(zone, epoch, log);
  EXPECT_FALSE(a.read_checkpoint(zone, 10).has_value());  // none written
  const auto chunk = [](int x, uint64_t seq, uint8_t v) {
    return ChunkRecord{{x, 0, -1}, seq, {v, v}};
  };
  a.write_checkpoint(epoch, {.zone = zone, .seq = 3, .chunks = {chunk(32, 3, 1), chunk(33, 3, 2)}});
  a.write_checkpoint(epoch, {.zone = zone, .seq = 5, .chunks = {chunk(33, 5, 3)}});
  const std::optional<ZoneCheckpoint> cp = a.read_checkpoint(zone, 3);
  ASSERT_TRUE(cp);
  EXPECT_EQ(cp->seq, 5u);
  ASSERT_EQ(cp->chunks.size(), 2u);
  EXPECT_EQ(cp->chunks[0].coord.x, 32);
  EXPECT_EQ(cp->chunks[0].samples, (std::vector<uint8_t>{1, 1}));  // unchanged since 3
  EXPECT_EQ(cp->chunks[1].seq, 5u);
  EXPECT_EQ(cp->chunks[1].samples, (std::vector<uint8_t>{3, 3}));
  EXPECT_EQ(cp->edit_ids, (std::vector<uint64_t>{102, 103, 104}));  // the last 3 through 5
  EXPECT_EQ(a.read(zone)->checkpoint_seq, 5u);
  // An older checkpoint (a retry) changes nothing; one past the log's end is refused.
  a.write_checkpoint(epoch, {.zone = zone, .seq = 4, .chunks = {chunk(32, 4, 9)}});
  EXPECT_EQ(a.read_checkpoint(zone, 3)->chunks[0].samples, (std::vector<uint8_t>{1, 1}));
  EXPECT_THROW(a.write_checkpoint(epoch, {.zone = zone, .seq = 7, .chunks = {}}), StoreError);
  EXPECT_THROW(a.write_checkpoint(epoch, {.zone = zone, .seq = 6, .chunks = {chunk(32, 7, 1)}}),
               StoreError);  // a chunk past its checkpoint
  EXPECT_EQ(a.fenced(), 0u);
}

// A changed chunk a holder evicted is read back alone: its latest version through the
// zone's checkpoint, and only by a world that applied the zone's records at least that far
// (a world behind a successor's checkpoint would apply records twice on it).
TEST_F(ZoneLeasesTest, AnEvictedChunkIsReadBackAtTheZonesCheckpointOnlyByAWorldThatFar) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  const ZoneId zone{0, 0};
  EXPECT_FALSE(a.read_chunk(zone, {1, 1, 1}, 0).has_value());  // no zone row yet
  const uint64_t epoch = *a.acquire(zone);
  a.append(zone, epoch, records(1, 6));
  EXPECT_FALSE(a.read_chunk(zone, {1, 1, 1}, 6).has_value());  // no checkpoint holds it
  a.write_checkpoint(epoch, {.zone = zone, .seq = 3, .chunks = {{{1, 1, 1}, 3, {3}}}});
  a.write_checkpoint(epoch, {.zone = zone, .seq = 5, .chunks = {{{2, 1, 1}, 5, {5}}}});
  std::optional<ChunkRecord> c = a.read_chunk(zone, {1, 1, 1}, 6);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->seq, 3u);  // unchanged since 3
  EXPECT_EQ(c->samples, (std::vector<uint8_t>{3}));
  EXPECT_EQ(a.read_chunk(zone, {2, 1, 1}, 5)->samples, (std::vector<uint8_t>{5}));
  EXPECT_FALSE(a.read_chunk(zone, {3, 1, 1}, 5).has_value());
  EXPECT_THROW(a.read_chunk(zone, {1, 1, 1}, 4), StoreError);  // behind the checkpoint
  // A version past the zone's checkpoint (a write refused after its chunks landed: here,
  // past the log's end) is never read back.
  EXPECT_THROW(a.write_checkpoint(epoch, {.zone = zone, .seq = 9, .chunks = {{{1, 1, 1}, 9, {9}}}}),
               StoreError);
  c = a.read_chunk(zone, {1, 1, 1}, 6);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->seq, 3u);
  EXPECT_EQ(c->samples, (std::vector<uint8_t>{3}));
}

// The safety rule for checkpoints: a holder paused past its lease cannot move the
// zone's checkpoint after its successor took it, and what it wrote before the fence
// refused it is never read.
TEST_F(ZoneLeasesTest, AStaleHoldersCheckpointIsFencedAndItsChunksAreNeverRead) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(300)), b(db, "b", milliseconds(30000));
  const ZoneId zone{0, 0};
  const uint64_t first = hold_then_pause(a, zone, 4, [&](uint64_t epoch) {
    a.write_checkpoint(epoch, {.zone = zone, .seq = 2, .chunks = {{{1, 1, 1}, 2, {2}}}});
  });
  const uint64_t second = *b.acquire(zone);
  b.append(zone, second, records(5, 1));
  EXPECT_THROW(a.write_checkpoint(first, {.zone = zone, .seq = 4, .chunks = {{{1, 1, 1}, 4, {4}}}}),
               FencedError);
  EXPECT_EQ(a.fenced(), 1u);
  std::optional<ZoneCheckpoint> cp = b.read_checkpoint(zone, 10);
  ASSERT_TRUE(cp);
  EXPECT_EQ(cp->seq, 2u);
  ASSERT_EQ(cp->chunks.size(), 1u);
  EXPECT_EQ(cp->chunks[0].samples, (std::vector<uint8_t>{2}));
  // The successor's checkpoint replaces it. A version past the zone's checkpoint_seq (a
  // write refused after its chunks landed: here, past the log's end) is never read.
  b.write_checkpoint(second, {.zone = zone, .seq = 5, .chunks = {{{1, 1, 1}, 5, {5}}}});
  EXPECT_THROW(
      b.write_checkpoint(second, {.zone = zone, .seq = 9, .chunks = {{{2, 2, 2}, 9, {9}}}}),
      StoreError);
  cp = b.read_checkpoint(zone, 10);
  ASSERT_TRUE(cp);
  EXPECT_EQ(cp->seq, 5u);
  ASSERT_EQ(cp->chunks.size(), 1u);
  EXPECT_EQ(cp->chunks[0].samples, (std::vector<uint8_t>{5}));
}

// A connection opened while another node's append holds a zone row's lock (a follower
// starting beside a busy holder) must not wait for it: creating the schema when it is
// there already locked the tables whole, and the new connection timed out.
TEST_F(ZoneLeasesTest, AConnectionOpenedWhileAZoneRowIsLockedDoesNotWaitForIt) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  a.acquire({0, 0});
  pqxx::connection holder(db);
  pqxx::work t(holder);
  t.exec("SELECT epoch FROM zones WHERE zone = 0 FOR UPDATE");  // an append in flight
  const auto start = std::chrono::steady_clock::now();
  ZoneLeases b(db, "b", milliseconds(400));  // its lock_timeout: 100 ms
  EXPECT_TRUE(b.read({0, 0}).has_value());
  EXPECT_LT(std::chrono::steady_clock::now() - start, milliseconds(2000));
  t.abort();
}

// A migration seeds its zones whole or not at all: one zone with records already refuses
// the lot, and the others are left empty (a half-seeded world could not be migrated again).
TEST_F(ZoneLeasesTest, AMigrationRefusedForOneZoneSeedsNone) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(30000));
  const ZoneId fresh{0, 0}, used{1, 0};
  const uint64_t e1 = *a.acquire(fresh), e2 = *a.acquire(used);
  a.append(used, e2, records(1, 1));
  const std::vector<ZoneSeed> seeds = {{fresh, e1, {{{0, 0, 0}, 1, {1}}}},
                                       {used, e2, {{{64, 0, 0}, 1, {2}}}}};
  EXPECT_THROW(a.seed_zones(seeds), StoreError);
  EXPECT_EQ(a.read(fresh)->last_seq, 0u);
  EXPECT_FALSE(a.read_checkpoint(fresh, 0).has_value());
  a.seed_zones(std::vector<ZoneSeed>{seeds[0]});
  EXPECT_EQ(a.read(fresh)->checkpoint_seq, 1u);
  EXPECT_EQ(a.read_checkpoint(fresh, 0)->chunks.size(), 1u);
}

TEST_F(ZoneLeasesTest, LiveNodesAreThoseWhoseHeartbeatIsWithinTheLease) {
  const std::string db = fresh_database();
  ZoneLeases a(db, "a", milliseconds(300)), b(db, "b", milliseconds(30000));
  a.heartbeat("127.0.0.1:7777");
  b.heartbeat("127.0.0.1:7778");
  EXPECT_EQ(b.live_nodes(), (std::vector<std::string>{"a", "b"}));
  std::this_thread::sleep_for(milliseconds(400));
  EXPECT_EQ(b.live_nodes(), (std::vector<std::string>{"b"}));
  a.heartbeat("127.0.0.1:7777");
  EXPECT_EQ(b.live_nodes(), (std::vector<std::string>{"a", "b"}));
}

// Two processes given one node id (a copied configuration, a restart racing its earlier
// run): the first keeps the id while its heartbeat runs; the second is told where it is.
TEST_F(ZoneLeasesTest, ANodeIdIsOneProcesssWhileItsHeartbeatRuns) {
  const std::string db = fresh_database();
  const milliseconds lease(2000);
  ZoneLeases first(db, "a", lease), second(db, "a", lease);
  EXPECT_FALSE(first.heartbeat("127.0.0.1:7777").has_value());
  EXPECT_EQ(second.heartbeat("127.0.0.1:8888"), std::optional<std::string>("127.0.0.1:7777"));
  EXPECT_FALSE(first.heartbeat("127.0.0.1:7777").has_value());  // still the first's
  second.leave();                                               // leaves nothing of the first's
  EXPECT_EQ(first.live_nodes(), (std::vector<std::string>{"a"}));
  // A row an earlier version wrote (no mark) is honoured the same way.
  {
    pqxx::connection c(db);
    pqxx::work t(c);
    t.exec(
        "INSERT INTO nodes (node, address, alive_until) "
        "VALUES ('old', '10.0.0.9:7777', now() + interval '2 seconds')");
    t.commit();
  }
  ZoneLeases upgraded(db, "old", lease);
  EXPECT_EQ(upgraded.heartbeat("127.0.0.1:9999"), std::optional<std::string>("10.0.0.9:7777"));
  upgraded.leave();
  EXPECT_EQ(first.live_nodes(), (std::vector<std::string>{"a", "old"}));
  std::this_thread::sleep_for(lease + milliseconds(200));  // the first stopped (kill -9)
  EXPECT_FALSE(second.heartbeat("127.0.0.1:8888").has_value());
  EXPECT_EQ(first.heartbeat("127.0.0.1:7777"), std::optional<std::string>("127.0.0.1:8888"));
  EXPECT_FALSE(upgraded.heartbeat("127.0.0.1:9999").has_value());
}

// A database an earlier version made (no checkpoint_seq, edit ids or process marks) gets
// the missing columns and index, its rows kept, and works.
TEST_F(ZoneLeasesTest, AnOlderDatabaseGetsTheMissingColumnsAndKeepsItsRows) {
  const std::string db = fresh_database();
  {
    pqxx::connection c(db);
    pqxx::work t(c);
    t.exec(
        "CREATE TABLE zones (zone BIGINT PRIMARY KEY, epoch BIGINT NOT NULL, owner TEXT, "
        "lease_until TIMESTAMPTZ NOT NULL, last_seq BIGINT NOT NULL DEFAULT 0);"
        "CREATE TABLE zone_log (zone BIGINT NOT NULL, seq BIGINT NOT NULL, epoch BIGINT NOT NULL, "
        "at_ms BIGINT NOT NULL, record BYTEA NOT NULL, PRIMARY KEY (zone, seq));"
        "CREATE TABLE nodes (node TEXT PRIMARY KEY, address TEXT NOT NULL, "
        "alive_until TIMESTAMPTZ NOT NULL);"
        "INSERT INTO zones VALUES (5, 3, NULL, now(), 0);");
    t.commit();
  }
  ZoneLeases a(db, "a", milliseconds(2000));
  EXPECT_EQ(a.acquire(world::ZoneId::from_key(5)), std::optional<uint64_t>(4));
  EXPECT_FALSE(a.heartbeat("127.0.0.1:7777").has_value());
  ZoneLeases again(db, "b", milliseconds(2000));  // the schema is whole now: nothing altered
  EXPECT_EQ(again.live_nodes(), (std::vector<std::string>{"a"}));
}

TEST_F(ZoneLeasesTest, BadSettingsAndAnUnreachableDatabaseAreOneLineErrors) {
  const std::string db = fresh_database();
  EXPECT_THROW(ZoneLeases(db, "", milliseconds(1000)), StoreError);
  EXPECT_THROW(ZoneLeases(db, "a", milliseconds(10)), StoreError);
  try {
    ZoneLeases gone("postgresql:///nowhere?host=/nonexistent&user=x&password=secret", "a",
                    milliseconds(1000));
    FAIL() << "no error";
  } catch (const StoreError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.find("secret"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace vox::store
