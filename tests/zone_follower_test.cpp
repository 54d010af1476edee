// Following a zone's committed records (server/cluster/zone_follower.hpp) against a real
// PostgreSQL and nats-server: a replica fed by an owner whose messages get lost still
// equals a replay of the zone's log, byte for byte.
#include "server/cluster/zone_follower.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <mutex>
#include <random>
#include <thread>

#include "server/cluster/zone_publisher.hpp"
#include "server/cluster/zone_replicas.hpp"
#include "server/cluster/zone_wire.hpp"
#include "server/store/edit_codec.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/eventually.hpp"
#include "tests/nats_server.hpp"
#include "tests/postgres_server.hpp"

namespace vox::cluster {
namespace {

using std::chrono::milliseconds;
using test::eventually;
using world::ZoneId;

constexpr uint64_t kSeed = 1234;
constexpr int kZoneChunks = 2;  // zones of 64 × 64 voxels

TEST(ZoneWire, RecordsAndHeartbeatsGoThereAndBackAndAnythingElseIsRefused) {
  const ZoneId zone{-3, 7};
  const store::ZoneRecord r{42, 1700000000123, {1, 2, 3}};
  const auto m = decode_zone_message(encode_zone_record(zone, r));
  ASSERT_TRUE(m);
  EXPECT_FALSE(m->heartbeat);
  EXPECT_EQ(m->zone, zone);
  EXPECT_EQ(m->record.seq, 42u);
  EXPECT_EQ(m->record.unix_ms, 1700000000123);
  EXPECT_EQ(m->record.payload, r.payload);
  const auto hb = decode_zone_message(encode_zone_heartbeat(zone, 99));
  ASSERT_TRUE(hb);
  EXPECT_TRUE(hb->heartbeat);
  EXPECT_EQ(hb->record.seq, 99u);
  std::vector<uint8_t> bad = encode_zone_heartbeat(zone, 1);
  bad.push_back(0);  // a heartbeat has an exact size
  EXPECT_FALSE(decode_zone_message(bad));
  EXPECT_FALSE(decode_zone_message(std::vector<uint8_t>{2, 1}));            // another version
  EXPECT_FALSE(decode_zone_message(std::vector<uint8_t>{1, 1, 0}));         // short
  EXPECT_FALSE(decode_zone_message(encode_zone_record(zone, {0, 0, {}})));  // seq 0
  EXPECT_EQ(zone_subject("w1", {0, 1}, "rec"), "vox.w1.zone.1.rec");
  EXPECT_FALSE(valid_world_name("a.b"));  // would split the subject
  EXPECT_FALSE(valid_world_name("*"));
  EXPECT_TRUE(valid_world_name("main_world-2"));
}

// An edit as a record's payload: there and back with its author and the samples it
// keeps; anything else is refused with a reason, never trusted.
TEST(ZoneWire, EditRecordsGoThereAndBackAndDamagedOnesAreRefused) {
  store::LoggedEdit e;
  e.author = "player-7";
  e.edit = world::Explosion{{64.0f, 10.0f, 64.0f}, 6.0f, 1.5f};
  e.keep = {world::VoxelBox{{1, 2, 3}, {4, 5, 6}}};
  const store::ZoneRecord r{9, 123, encode_zone_edit(e)};
  const auto back = decode_zone_edit(r);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->seq, 9u);
  EXPECT_EQ(back->unix_ms, 123);
  EXPECT_EQ(back->author, "player-7");
  EXPECT_EQ(back->keep.size(), 1u);
  EXPECT_EQ(store::encode_edit(back->edit, back->keep), store::encode_edit(e.edit, e.keep));
  std::string why;
  for (size_t cut = 0; cut < r.payload.size(); ++cut) {
    store::ZoneRecord shorter = r;
    shorter.payload.resize(cut);
    EXPECT_FALSE(decode_zone_edit(shorter, &why)) << cut;
    EXPECT_FALSE(why.empty());
  }
  store::ZoneRecord other = r;
  other.payload[0] = 9;  // a version this build does not know
  EXPECT_FALSE(decode_zone_edit(other, &why));
  other = r;
  other.payload[1] = 0xff;  // an author longer than the record
  other.payload[2] = 0xff;
  EXPECT_FALSE(decode_zone_edit(other, &why));
}

// The owner's side in miniature: edits replayed into its samples, appended to the zone's
// log under its epoch, and published (or not: `lose` says which are lost on the way).
struct Owner {
  Owner(const std::string& db, NatsLink& nats, ZoneId zone)
      : leases(db, "owner", milliseconds(30000)), nats(nats), zone(zone) {
    epoch = *leases.acquire(zone);
  }
  world::Edit random_edit(std::mt19937& rng) {
    std::uniform_real_distribution<float> xz(4.0f, kZoneChunks * 32 - 4.0f), y(-24.0f, 24.0f);
    const world::Vec3 c{zone.x * kZoneChunks * 32 + xz(rng), y(rng),
                        zone.z * kZoneChunks * 32 + xz(rng)};
    if (rng() % 2) return world::Explosion{c, 3.0f, 1.0f};
    return world::Brush{c, 3.0f, 0.8f};
  }
  void edit(const world::Edit& e, bool lose) {
    world::replay_edit(truth, generator, e);
    const store::ZoneRecord r{++seq, 1000 + static_cast<int64_t>(seq), store::encode_edit(e)};
    leases.append(zone, epoch, std::vector<store::ZoneRecord>{r});
    if (!lose) nats.publish(zone_subject("w", zone, "rec"), encode_zone_record(zone, r));
  }
  void heartbeat() {
    nats.publish(zone_subject("w", zone, "hb"), encode_zone_heartbeat(zone, seq));
  }

  store::ZoneLeases leases;
  NatsLink& nats;
  ZoneId zone;
  uint64_t epoch = 0, seq = 0;
  world::TerrainGenerator generator{kSeed};
  world::ChunkMap truth;
};

// The replica's side: records decoded and replayed with the same code.
struct Replica {
  void apply(const store::ZoneRecord& r) {
    const auto record = store::decode_edit_record(r.payload);
    ASSERT_TRUE(record);
    world::replay_edit(map, generator, record->edit, record->keep);
    seqs.push_back(r.seq);
  }
  world::TerrainGenerator generator{kSeed};
  world::ChunkMap map;
  std::vector<uint64_t> seqs;  // follower thread only, read after applied() says so
};

void expect_same_samples(const world::ChunkMap& truth, const world::ChunkMap& replica) {
  size_t compared = 0;
  for (const auto& [c, chunk] : truth) {
    const world::Chunk* other = replica.find(c);
    ASSERT_TRUE(other) << "chunk " << c.x << "," << c.y << "," << c.z << " missing";
    EXPECT_TRUE(*other == chunk) << "chunk " << c.x << "," << c.y << "," << c.z << " differs";
    ++compared;
  }
  EXPECT_GT(compared, 0u);  // not a comparison of nothing
}

// The replica applied records 1 .. n, in order, and holds the owner's samples.
void expect_replica_matches(const Owner& owner, const Replica& replica, size_t n) {
  ASSERT_EQ(replica.seqs.size(), n);
  for (size_t i = 0; i < n; ++i) EXPECT_EQ(replica.seqs[i], i + 1);
  expect_same_samples(owner.truth, replica.map);
}

class ZoneFollowerTest : public ::testing::Test {
 protected:
  test::PostgresServer postgres;
  test::NatsServer nats_server;
  NatsConfig nats_config(const std::string& name) {
    return {.url = nats_server.url(),
            .user = test::NatsServer::kUser,
            .password = test::NatsServer::kPassword,
            .name = name};
  }
};

TEST_F(ZoneFollowerTest, AReplicaFollowingAnOwnerWhoseMessagesGetLostEqualsAReplayOfTheLog) {
  const std::string db = postgres.create_database("follow1");
  NatsLink owner_link(nats_config("owner")), replica_link(nats_config("replica"));
  const ZoneId zone{1, -1};
  Owner owner(db, owner_link, zone);
  Replica replica;
  ZoneFollower follower(replica_link, {.world = "w", .zone = zone, .uri = db, .node = "replica"},
                        [&](const store::ZoneRecord& r) { replica.apply(r); });
  std::mt19937 rng(7);
  for (int i = 1; i <= 120; ++i) {
    owner.edit(owner.random_edit(rng), /*lose=*/i % 7 == 3 || i > 116);
    if (i % 20 == 0) owner.heartbeat();
  }
  owner.heartbeat();  // the last records were lost: the heartbeat tells there are more
  // Garbage and another zone's record on this zone's subject: dropped, counted.
  owner_link.publish(zone_subject("w", zone, "rec"), std::vector<uint8_t>{9, 9, 9});
  owner_link.publish(zone_subject("w", zone, "rec"),
                     encode_zone_record({5, 5}, {121, 0, store::encode_edit(world::Brush{})}));
  ASSERT_TRUE(eventually([&] { return follower.applied() == 120 && follower.dropped() == 2; },
                         milliseconds(15000)))
      << "applied " << follower.applied() << ", dropped " << follower.dropped();
  EXPECT_GT(follower.filled(), 0u) << "the lost records came from the log";
  expect_replica_matches(owner, replica, 120);
}

// Records are published only after commit, so a heartbeat claiming more than the log has is
// false: the follower read the log every 50 ms for ever to find it.
TEST_F(ZoneFollowerTest, AHeartbeatClaimingRecordsTheLogLacksIsDroppedNotChasedForEver) {
  const std::string db = postgres.create_database("follow4");
  NatsLink owner_link(nats_config("owner")), replica_link(nats_config("replica"));
  const ZoneId zone{4, 4};
  Owner owner(db, owner_link, zone);
  Replica replica;
  ZoneFollower follower(replica_link, {.world = "w", .zone = zone, .uri = db, .node = "replica"},
                        [&](const store::ZoneRecord& r) { replica.apply(r); });
  std::mt19937 rng(3);
  owner.edit(owner.random_edit(rng), false);
  ASSERT_TRUE(eventually([&] { return follower.applied() == 1; }));
  owner_link.publish(zone_subject("w", zone, "hb"), encode_zone_heartbeat(zone, 1000000));
  ASSERT_TRUE(eventually([&] { return follower.dropped() == 1; }));
  EXPECT_EQ(follower.applied(), 1u);
  owner.edit(owner.random_edit(rng), false);  // and real records still come
  ASSERT_TRUE(eventually([&] { return follower.applied() == 2; }));
  expect_replica_matches(owner, replica, 2);
}

TEST_F(ZoneFollowerTest, AFollowerThatStartsLateReadsTheLogThenFollowsTheSubject) {
  const std::string db = postgres.create_database("follow2");
  NatsLink owner_link(nats_config("owner")), replica_link(nats_config("replica"));
  const ZoneId zone{0, 0};
  Owner owner(db, owner_link, zone);
  std::mt19937 rng(11);
  for (int i = 0; i < 40; ++i) owner.edit(owner.random_edit(rng), false);  // nobody listens yet
  Replica replica;
  ZoneFollower follower(replica_link, {.world = "w", .zone = zone, .uri = db, .node = "replica"},
                        [&](const store::ZoneRecord& r) { replica.apply(r); });
  ASSERT_TRUE(eventually([&] { return follower.applied() == 40; }));
  EXPECT_EQ(follower.filled(), 40u);
  for (int i = 0; i < 40; ++i) owner.edit(owner.random_edit(rng), false);
  ASSERT_TRUE(eventually([&] { return follower.applied() == 80; }));
  EXPECT_LT(follower.filled(), 80u) << "the later ones came over NATS";
  expect_replica_matches(owner, replica, 80);
}

// The owner's side as voxeld will run it (ZonePublisher): commits reach a follower across
// a NATS outage, and an owner whose zone was taken meanwhile publishes nothing.
TEST_F(ZoneFollowerTest, AnOwnersCommitsReachAFollowerAcrossANatsRestartAndAFencedOneSendsNothing) {
  const std::string db = postgres.create_database("follow3");
  NatsLink owner_link(nats_config("owner")), replica_link(nats_config("replica"));
  const ZoneId zone{2, 3};
  Owner owner(db, owner_link, zone);  // its leases and samples; commits go through the publisher
  ZonePublisher publisher(owner_link, owner.leases, "w");
  publisher.adopt(zone, owner.leases.read(zone)->last_seq);
  Replica replica;
  ZoneFollower follower(replica_link, {.world = "w", .zone = zone, .uri = db, .node = "replica"},
                        [&](const store::ZoneRecord& r) { replica.apply(r); });
  std::mt19937 rng(5);
  const auto commit = [&](int edits) {
    std::vector<std::vector<uint8_t>> payloads;
    for (int i = 0; i < edits; ++i) {
      const world::Edit e = owner.random_edit(rng);
      world::replay_edit(owner.truth, owner.generator, e);
      payloads.push_back(store::encode_edit(e));
    }
    return publisher.commit(zone, owner.epoch, payloads, 1000);
  };
  EXPECT_EQ(commit(3), (std::pair<uint64_t, uint64_t>{1, 3}));
  for (int i = 0; i < 7; ++i) commit(1);
  ASSERT_TRUE(eventually([&] { return follower.applied() == 10; }));
  nats_server.stop();
  for (int i = 0; i < 5; ++i) commit(2);  // durable in the log; NATS is down
  nats_server.restart();
  ASSERT_TRUE(
      eventually([&] { return owner_link.reconnects() >= 1 && replica_link.reconnects() >= 1; }));
  commit(1);
  ASSERT_TRUE(eventually([&] {
    publisher.heartbeat();  // until the follower's interest is back on the server
    return follower.applied() == 21;
  }));
  expect_replica_matches(owner, replica, 21);
  // Another node takes the zone (released here rather than waiting out the owner's 30 s
  // lease); the old owner still commits at its old epoch.
  owner.leases.release(zone, owner.epoch);
  store::ZoneLeases taker(db, "taker", milliseconds(30000));
  ASSERT_TRUE(taker.acquire(zone).has_value());
  EXPECT_THROW(commit(1), store::FencedError);
  std::this_thread::sleep_for(milliseconds(200));
  EXPECT_EQ(follower.applied(), 21u) << "a fenced commit reached a follower";
}

// Records a node could not apply, given back while its follower queued later ones (and
// the same ones, read again from the log), are taken again in sequence order, each once:
// given back in front of the queue, they were taken twice (a zone's record applied twice).
TEST_F(ZoneFollowerTest, RecordsGivenBackBesideLaterOnesAreTakenInOrderEachOnce) {
  const std::string db = postgres.create_database("replicas");
  NatsLink link(nats_config("replicas"));
  const ZoneId zone{0, 0};
  store::ZoneLeases(db, "setup", milliseconds(30000)).settle_world({"w", kSeed, kZoneChunks});
  ZoneReplicas replicas(link, {.world = "w", .uri = db, .node = "replica"}, [] {});
  EXPECT_TRUE(replicas.viewing(zone));   // new: the node starts a reconcile at once
  EXPECT_FALSE(replicas.viewing(zone));  // viewed and followed: nothing to start
  const auto never = [](ZoneId) { return false; };
  replicas.reconcile(never, [](ZoneId) { return uint64_t{0}; });
  ASSERT_TRUE(replicas.following(zone));
  const auto records = [](uint64_t first, uint64_t last) {
    std::vector<store::ZoneRecord> out;
    for (uint64_t seq = first; seq <= last; ++seq) out.push_back({seq, 0, {1}});
    return out;
  };
  replicas.give_back(zone, records(11, 15));  // queued by the follower meanwhile
  replicas.give_back(zone, records(6, 12));   // the pipeline could not apply these
  const auto taken = replicas.take(100, never, [](ZoneId) { return uint64_t{7}; });
  ASSERT_TRUE(taken);
  std::vector<uint64_t> seqs;
  for (const auto& r : taken->records) seqs.push_back(r.seq);
  EXPECT_EQ(seqs, (std::vector<uint64_t>{8, 9, 10, 11, 12, 13, 14, 15}));
  replicas.stop();
}

// A zone with a checkpoint: a follower new to it starts after the checkpoint (the node
// installs it), and a migrated zone, whose log starts at record 2, is followed too.
TEST_F(ZoneFollowerTest, AFollowerNewToAZoneWithACheckpointStartsAfterIt) {
  const std::string db = postgres.create_database("follow_cp");
  NatsLink owner_link(nats_config("owner")), replica_link(nats_config("replica"));
  const ZoneId zone{0, 0};
  store::ZoneLeases seeder(db, "seeder", milliseconds(30000));
  const uint64_t epoch = *seeder.acquire(zone);
  seeder.seed_zones(std::vector<store::ZoneSeed>{{zone, epoch, {{{0, 0, 0}, 1, {7}}}}});
  seeder.release(zone, epoch);
  Owner owner(db, owner_link, zone);
  owner.seq = 1;  // the migrated checkpoint is record 1
  std::mt19937 rng(5);
  for (int i = 0; i < 5; ++i) owner.edit(owner.random_edit(rng), false);
  std::vector<uint64_t> seqs;
  std::mutex mutex;
  ZoneFollower follower(replica_link, {.world = "w", .zone = zone, .uri = db, .node = "replica"},
                        [&](const store::ZoneRecord& r) {
                          std::lock_guard lock(mutex);
                          seqs.push_back(r.seq);
                        });
  ASSERT_TRUE(eventually([&] { return follower.applied() == 6; }));
  std::lock_guard lock(mutex);
  EXPECT_EQ(seqs, (std::vector<uint64_t>{2, 3, 4, 5, 6}));
}

}  // namespace
}  // namespace vox::cluster
