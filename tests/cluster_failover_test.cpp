// A cluster world's faults (docs/CLUSTER.md): kill -9 and SIGSTOP of a zone's holder under
// editing, NATS restarted, PostgreSQL down, a node joining under load. Each checks the
// zones' logs: every accepted edit in them exactly once, and the nodes' worlds equal to
// the logs replayed (tests/cluster_test_util.hpp).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <pqxx/pqxx>
#include <sstream>

#include "tests/child_process.hpp"
#include "tests/cluster_test_util.hpp"
#include "tests/metrics_scrape.hpp"

namespace vox::test {
namespace {

// The failover check: players on two nodes edit the zones a third node holds
// (their edits forwarded to it) while it is killed with SIGKILL; the others take its zones
// over once its leases run out. Every edit a player saw ACCEPTED is in its zone's log
// exactly once, and the nodes' worlds equal a single node replaying those logs.
// With VOXEL_FAULT_EVICT=1 (bench/scripts/cluster_faults.sh), the nodes evict their zones'
// changed chunks after a second and read them back from the checkpoints (taken every
// 0.2 s) as the edits need them.
TEST(ClusterNode, KillNineOfAHolderUnderEditingLosesNoAcceptedEditAndAppliesNoneTwice) {
  const Cluster cluster;
  const std::vector<world::ZoneId> zones = zones_ranked_first_by("c", {"a", "b", "c"}, 2);
  ASSERT_EQ(zones.size(), 2u);
  const char* evict = std::getenv("VOXEL_FAULT_EVICT");
  const auto args = [&](const std::string& node) {
    std::vector<std::string> out = {"--cluster", cluster.config(node)};
    if (evict && std::string(evict) == "1")
      out.insert(out.end(),
                 {"--evict-after", "1", "--checkpoint-interval", "0.2", "--metrics-port", "0"});
    return out;
  };
  ServerProcess a(args("a"));
  ServerProcess b(args("b"));
  auto c = std::make_unique<ServerProcess>(args("c"));
  EditingLoad load({&a, &b}, zones);  // through a and b: c holds the zones
  ASSERT_TRUE(eventually(
      nullptr, [&] { return load.accepted() >= 20; }, 20s))
      << "no edits accepted";
  const size_t at_kill = load.accepted();
  const auto killed_at = std::chrono::steady_clock::now();
  c.reset();  // SIGKILL
  const bool recovered = eventually(
      nullptr, [&] { return load.accepted() >= at_kill + 20; }, 30s);
  // Evicting: a few seconds more, so that the survivors evict chunks of the zones they
  // took and read them back as the players edit on.
  if (recovered && evict && std::string(evict) == "1") std::this_thread::sleep_for(5s);
  load.stop();
  ASSERT_TRUE(recovered) << "c's zones were not writable again";
  if (evict && std::string(evict) == "1") {
    for (const ServerProcess* n : {&a, &b})
      std::printf("a survivor evicted %.0f chunks\n",
                  scrape(n->metrics_port()).at("voxeld_chunks_evicted_total"));
  }
  // The survivors show what a single node replaying the logs shows.
  expect_nodes_show({&a, &b}, zones, load.check_logs(cluster.database));
  // Not a timed test: the figure is printed for docs/PERFORMANCE.md, never asserted.
  std::printf(
      "accepted %zu edits (%zu before the kill), %d refused during the failover; the first "
      "edit sent after the kill and accepted was answered %.0f ms after it (lease 1 s)\n",
      load.accepted(), at_kill, load.refused(), load.first_accepted_after_ms(killed_at));
}

// A node joining under load: the zones it now ranks first for are handed over to it (the
// old holder releases them; the next edit's take makes the newcomer take them). No
// accepted edit is lost or logged twice, and the edits of those zones stall briefly.
TEST(ClusterNode, ANodeJoiningUnderLoadTakesItsZonesOverLosingNothing) {
  const Cluster cluster;
  // Zones b will rank first for once it joins a.
  const std::vector<world::ZoneId> zones = zones_ranked_first_by("b", {"a", "b"}, 2);
  ASSERT_EQ(zones.size(), 2u);
  ServerProcess a({"--cluster", cluster.config("a")});
  EditingLoad load({&a, &a}, zones);  // a alone holds them at first
  ASSERT_TRUE(eventually(
      nullptr, [&] { return load.accepted() >= 20; }, 20s))
      << "no edits accepted";
  const auto joined_at = std::chrono::steady_clock::now();
  ServerProcess b({"--cluster", cluster.config("b"), "--metrics-port", "0"});
  // a hands the zones over once its round sees b alive (within a lease or so; slower
  // under a sanitizer); then edits must go on through b.
  const bool handed = eventually(
      nullptr, [&] { return scrape(b.metrics_port()).at("voxeld_cluster_zones_held") >= 1; }, 20s);
  const size_t at_hand_off = load.accepted();
  const bool went_on = eventually(
      nullptr, [&] { return load.accepted() >= at_hand_off + 40; }, 30s);
  load.stop();
  ASSERT_TRUE(handed) << "b took none of its zones";
  ASSERT_TRUE(went_on) << "the zones were not writable after the hand-off";
  expect_nodes_show({&a, &b}, zones, load.check_logs(cluster.database));
  // A graceful hand-off refuses nothing: a takes no more edits in the zones, lets its
  // appends land, releases, and what comes meanwhile waits for b (the gateway asks again).
  // It once refused the batches in flight, and rested the whole store a second for them.
  // (Under a sanitizer an append may outlast the hand-off's grace: not counted there.)
  if (kSlow == 1) {
    EXPECT_EQ(load.refused(), 0) << "a graceful hand-off refused edits";
  }
  // Not a timed test: printed for docs/PERFORMANCE.md.
  std::printf(
      "hand-off: %zu edits accepted, %d refused; the longest stall after b joined %.0f ms\n",
      load.accepted(), load.refused(), load.longest_gap_after_ms(joined_at));
}

// NATS restarted mid-run: records published while it was down are read from the zones'
// logs (heartbeats tell a follower what it missed), and the replica is the same again.
TEST(ClusterNode, AfterANatsRestartAReplicaFillsWhatItMissedFromTheLogs) {
  Cluster cluster;
  const auto [x_, z_] = middle_of_a_zone_of("a");
  const float x = x_, z = z_;
  ServerProcess a({"--cluster", cluster.config("a")});
  ServerProcess b({"--cluster", cluster.config("b")});
  auto viewer = player(b, "viewer");
  view(*viewer, x, surface_y(x, z), z, 1);
  std::vector<wire::Envelope> edits;
  for (int i = 0; i < 6; ++i)
    edits.push_back(
        brush(static_cast<uint64_t>(i + 1), x + static_cast<float>(i), z, 1 + i % 4, 3));
  auto editor = player(a, "editor");
  for (int i = 0; i < 6; ++i) {
    if (i == 3) cluster.nats.restart();  // edits go on: the holder needs no NATS to commit
    const wire::EditResult r = edit_until_accepted(*editor, edits[static_cast<size_t>(i)]);
    ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
  }
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  const Seen expected = view_of(fresh, x, z);
  EXPECT_TRUE(eventually(
      &b,
      [&] {
        wait_for(
            *viewer, [](const wire::Envelope&) { return false; }, 200ms);
        return held_by(*viewer) == expected;
      },
      20s))
      << "b's replica did not catch up after the NATS restart";
}

// PostgreSQL unreachable for a few seconds: edits are refused STORAGE_UNAVAILABLE (none is
// half applied), /healthz says 503 once a lease has passed, and edits are taken again once
// it is back, without restarting anything.
TEST(ClusterNode, WhilePostgresqlIsDownEditsAreRefusedAndAfterwardsTakenAgain) {
  PostgresServer pg;
  const std::string database = pg.create_database("down");
  NatsServer nats;
  const TempDir tmp("cluster_pg_down");
  ServerProcess a({"--cluster", node_config(tmp, "a", database, nats), "--http-port", "auto"});
  const auto health = [&] { return http_get(a.http_port(), "/healthz"); };
  auto editor = player(a, "editor");
  std::vector<wire::Envelope> accepted = {brush(1, 40, 40, 4)};
  ASSERT_EQ(edit_until_accepted(*editor, accepted[0]).status(), wire::EditResult::ACCEPTED);
  EXPECT_NE(health().find("200 OK"), std::string::npos) << health();
  pg.stop();
  const auto down = edit_and_wait(*editor, brush(2, 44, 40, 3));
  ASSERT_TRUE(down);
  EXPECT_EQ(down->edit_result().status(), wire::EditResult::STORAGE_UNAVAILABLE)
      << down->edit_result().reason();
  std::this_thread::sleep_for(2s);  // past the lease: the node no longer knows it holds it
  // A load balancer sends it no new players meanwhile (docs/haproxy-cluster.cfg).
  const std::string unhealthy = health();
  EXPECT_NE(unhealthy.find("503"), std::string::npos) << unhealthy;
  EXPECT_NE(unhealthy.find("has not reached the cluster's database"), std::string::npos)
      << unhealthy;
  pg.start();
  accepted.push_back(brush(3, 36, 40, 2));
  const wire::EditResult back = edit_until_accepted(*editor, accepted[1], 30s);
  EXPECT_EQ(back.status(), wire::EditResult::ACCEPTED) << back.reason();
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, accepted);
  EXPECT_TRUE(view_of(a, 40, 40) == view_of(fresh, 40, 40)) << "the refused edit left a trace";
  EXPECT_NE(health().find("200 OK"), std::string::npos) << health();
}

// An owner stopped past its lease (SIGSTOP) while another node takes its zone: when it
// wakes, an edit its player sent meanwhile is either refused — by the fence, if its
// append reached the database before its keeper noticed the loss, or by that notice —
// or, once it noticed, forwarded to the new holder and accepted there. Whichever way the
// race goes, nothing it did as a stale owner reaches anyone: the new holder's world is
// the zone's log replayed, and every accepted edit is in the log exactly once.
// Roll forward: an edit across zones of two nodes whose second holder is stopped. The
// first part is logged (leaving the second pending) and the player is answered; the
// stopped node's zone is taken by the other once its lease runs out, and the part left
// undone is completed there, once: the world is a single node's after the same edits.
TEST(ClusterNode, APartLeftUndoneByAStoppedHolderIsCompletedOnceItsZoneIsTaken) {
  const Cluster cluster;
  const ZonesApart apart = zones_held_apart();
  const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
  const float bx = apart.border_x(), z = apart.middle_z();
  const std::vector<wire::Envelope> edits = {
      brush(1, (static_cast<float>(apart.of_a.x) + 0.5f) * side, z, 4, 4.0f),
      brush(2, (static_cast<float>(apart.of_b.x) + 0.5f) * side, z, 2, 4.0f),
      explosion(3, bx + 0.5f, z)};
  ServerProcess a({"--cluster", cluster.config("a"), "--metrics-port", "0"});
  ServerProcess b({"--cluster", cluster.config("b")});
  auto editor = player(a, "editor");
  // Both zones taken and loaded by their nodes.
  ASSERT_EQ(edit_until_accepted(*editor, edits[0]).status(), wire::EditResult::ACCEPTED);
  ASSERT_EQ(edit_until_accepted(*editor, edits[1]).status(), wire::EditResult::ACCEPTED);
  ::kill(b.pid(), SIGSTOP);
  const auto across = edit_and_wait(*editor, edits[2], 20s * kSlow);
  ASSERT_TRUE(across);
  EXPECT_EQ(across->edit_result().status(), wire::EditResult::ACCEPTED)
      << across->edit_result().reason();
  EXPECT_TRUE(eventually(
      &a, [&] { return scrape(a.metrics_port()).at("voxeld_cluster_parts_completed_total") >= 1; },
      30s))
      << "a did not complete b's part once it took b's zone";
  ::kill(b.pid(), SIGKILL);
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  const Seen expected = view_of(fresh, bx, z);
  EXPECT_TRUE(eventually(&a, [&] { return view_of(a, bx, z) == expected; }))
      << "a does not show the edit across the border whole";
  // The edit's two parts, each once in its zone's log: its id is the one both logs have
  // (the other edits, forwarded or not, are in one zone each).
  const auto logged = edit_ids_logged(cluster.database, {apart.of_a, apart.of_b});
  int in_both = 0;
  for (const auto& [where, n] : logged) {
    EXPECT_EQ(n, 1);
    if (where.first == apart.of_a && logged.count({apart.of_b, where.second})) ++in_both;
  }
  EXPECT_EQ(in_both, 1) << "the edit across the border is not in both zones' logs";
}

// A player's edit carries its own edit id. Its node dies before the answer arrives (here:
// after it, which the node cannot tell apart); the player reconnects to another node and
// resends the edit: it is answered ACCEPTED with already_applied and applied once, whole
// edits and edits across zones of two nodes alike.
TEST(ClusterNode, AnEditResentThroughAnotherNodeAfterItsNodesDeathIsAppliedOnce) {
  const Cluster cluster;
  const ZonesApart apart = zones_held_apart();
  const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
  const float bx = apart.border_x(), z = apart.middle_z();
  std::vector<wire::Envelope> edits = {
      brush(1, (static_cast<float>(apart.of_a.x) + 0.5f) * side, z, 4, 4.0f),  // a's zone
      explosion(2, bx - 0.5f, z + 2.0f)};                                      // across
  edits[0].mutable_edit()->set_edit_id(0xabc);
  edits[1].mutable_edit()->set_edit_id(0xabd);
  ServerProcess a({"--cluster", cluster.config("a")});
  std::optional<ServerProcess> b(std::in_place,
                                 std::vector<std::string>{"--cluster", cluster.config("b")});
  {
    auto on_b = player(*b, "player-1");
    for (const auto& e : edits) {
      const wire::EditResult r = edit_until_accepted(*on_b, e);
      ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
      EXPECT_FALSE(r.already_applied());
    }
  }
  b.reset();                          // kill -9
  auto on_a = player(a, "player-1");  // the same player, on the node left
  for (const auto& e : edits) {
    const wire::EditResult r = edit_until_accepted(*on_a, e);
    EXPECT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
    EXPECT_TRUE(r.already_applied()) << "edit " << e.edit().request_id() << " applied again";
  }
  // Another player's edit with the same client id is another edit.
  auto other = player(a, "player-2");
  wire::Envelope theirs = brush(3, (static_cast<float>(apart.of_a.x) + 0.5f) * side, z + 8, 2, 3);
  theirs.mutable_edit()->set_edit_id(0xabc);
  const wire::EditResult r = edit_until_accepted(*other, theirs);
  EXPECT_EQ(r.status(), wire::EditResult::ACCEPTED);
  EXPECT_FALSE(r.already_applied());
  edits.push_back(theirs);
  for (auto& e : edits) e.mutable_edit()->clear_edit_id();  // one player replays them all
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  for (const float at_x : {bx, (static_cast<float>(apart.of_a.x) + 0.5f) * side}) {
    const Seen expected = view_of(fresh, at_x, z);
    EXPECT_TRUE(eventually(&a, [&] { return view_of(a, at_x, z) == expected; }))
        << "a resent edit was applied twice, or one was lost (x = " << at_x << ")";
  }
  for (const auto& [where, n] : edit_ids_logged(cluster.database, {apart.of_a, apart.of_b}))
    EXPECT_EQ(n, 1) << "edit " << where.second << " logged " << n << " times";
}

TEST(ClusterNode, AnOwnerStoppedPastItsLeaseIsFencedAndItsLateEditReachesNoOne) {
  const Cluster cluster;
  const auto [x_, z_] = middle_of_a_zone_of("a");
  const float x = x_, z = z_;
  const world::ZoneId zone = world::zone_of(
      world::chunk_of_voxel(static_cast<int32_t>(x), 0, static_cast<int32_t>(z)), kZoneChunks);
  ServerProcess a({"--cluster", cluster.config("a"), "--metrics-port", "0"});
  ServerProcess b({"--cluster", cluster.config("b")});
  const std::vector<wire::Envelope> edits = {brush(1, x, z, 4, 4.0f), brush(2, x + 3, z, 2, 4.0f),
                                             brush(3, x - 3, z, 5, 4.0f)};
  auto on_a = player(a, "early");
  ASSERT_EQ(edit_until_accepted(*on_a, edits[0]).status(), wire::EditResult::ACCEPTED);
  ::kill(a.pid(), SIGSTOP);
  // b takes the zone once a's heartbeat and lease have run out (1 s each).
  auto on_b = player(b, "later");
  const wire::EditResult taken = edit_until_accepted(*on_b, edits[1]);
  on_a->send(edits[2]);  // waits in a's socket: a wakes to it
  ::kill(a.pid(), SIGCONT);
  ASSERT_EQ(taken.status(), wire::EditResult::ACCEPTED) << taken.reason();
  const auto late = wait_for(*on_a, [](const wire::Envelope& m) { return m.has_edit_result(); });
  ASSERT_TRUE(late);
  const bool late_accepted = late->edit_result().status() == wire::EditResult::ACCEPTED;
  const auto metrics = scrape(a.metrics_port());
  const double fenced = metrics.at("voxeld_cluster_appends_fenced_total");
  std::printf("the late edit: %s (%s); a's appends fenced: %.0f\n",
              late_accepted ? "accepted through b" : "refused",
              late->edit_result().reason().c_str(), fenced);
  if (late_accepted) {
    EXPECT_GE(metrics.at("voxeld_cluster_edits_forwarded_total"), 1);
  }
  // The zone's log: the accepted edits, each once, and nothing else of a's.
  store::ZoneLeases reader(cluster.database, "test-reader", 3000ms);
  std::map<std::string, int> logged;
  std::vector<wire::Envelope> replay;
  for (const store::ZoneRecord& r : reader.read_log(zone, 0)) {
    const auto e = store::decode_zone_edit(r);
    ASSERT_TRUE(e);
    const auto bytes = store::encode_edit(e->edit);
    const std::string key(bytes.begin(), bytes.end());
    ++logged[key];
    for (const auto& sent : edits) {
      if (encoding_of(sent) == key) replay.push_back(sent);
    }
  }
  ASSERT_EQ(replay.size(), logged.size()) << "the log holds an edit nobody sent";
  const auto times_logged = [&](const wire::Envelope& e) {
    const auto it = logged.find(encoding_of(e));
    return it == logged.end() ? 0 : it->second;
  };
  EXPECT_EQ(times_logged(edits[0]), 1);
  EXPECT_EQ(times_logged(edits[1]), 1);
  EXPECT_EQ(times_logged(edits[2]), late_accepted ? 1 : 0);
  // b's world is that log replayed.
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, replay);
  const Seen expected = view_of(fresh, x, z);
  EXPECT_TRUE(eventually(&b, [&] { return view_of(b, x, z) == expected; }))
      << "b shows something other than the zone's log";
}

// A followed zone whose log holds a record that cannot be read (a damaged row) holds up no
// other followed zone: the zones take turns. (The first zone in order was taken every
// time and failed every time: the zones after it were never shown.)
TEST(ClusterNode, AFollowedZoneWithADamagedRecordHoldsUpNoOtherFollowedZone) {
  const Cluster cluster;
  const std::vector<world::ZoneId> zones = zones_ranked_first_by("a", {"a", "b"}, 2);
  ASSERT_EQ(zones.size(), 2u);
  const world::ZoneId damaged = std::min(zones[0], zones[1]), sound = std::max(zones[0], zones[1]);
  const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
  const auto middle = [&](world::ZoneId z) {
    return std::pair{(static_cast<float>(z.x) + 0.5f) * side,
                     (static_cast<float>(z.z) + 0.5f) * side};
  };
  const auto [dx, dz] = middle(damaged);
  const std::pair<float, float> sound_middle = middle(sound);
  const float sx = sound_middle.first, sz = sound_middle.second;  // captured below
  const std::vector<wire::Envelope> in_sound = {brush(1, sx, sz, 4, 5.0f),
                                                explosion(2, sx + 3, sz)};
  // No checkpoint: b reads the damaged record (a checkpoint past it would be installed).
  ServerProcess a({"--cluster", cluster.config("a"), "--checkpoint-interval", "3600"});
  apply_all(a, {brush(3, dx, dz, 2, 5.0f)});
  apply_all(a, in_sound);
  {
    pqxx::connection c(cluster.database);
    pqxx::work t(c);
    t.exec_params("UPDATE zone_log SET record = '\\x09'::bytea WHERE zone = $1 AND seq = 1",
                  static_cast<int64_t>(damaged.key()));
    t.commit();
  }
  ServerProcess b({"--cluster", cluster.config("b")});
  auto viewer = player(b, "viewer");  // b follows both zones, the damaged one first
  view(*viewer, dx, surface_y(dx, dz), dz, 1);
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, in_sound);
  const Seen expected = view_of(fresh, sx, sz);
  EXPECT_TRUE(eventually(
      &b, [&] { return view_of(b, sx, sz) == expected; }, 20s))
      << "the sound zone was never shown on b";
}

// A port nothing listens on now (for a program that cannot be given port 0).
uint16_t free_port() {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::acceptor a(io, {asio::ip::make_address("127.0.0.1"), 0});
  return a.local_endpoint().port();
}

// The documented deployment (docs/haproxy-cluster.cfg, run as written but for its
// addresses and the daemon lines): HAProxy in front of two nodes, checking each with
// GET /healthz. A player connects through it and its node dies (kill -9): connecting again
// through the same address it reaches the live node, where its edit is accepted once the
// dead node's zone is taken, and the dead node gets no new players.
TEST(ClusterNode, APlayerBehindHaproxyReachesALiveNodeAfterItsNodesDeath) {
  const std::string haproxy = "/usr/sbin/haproxy";
  if (!fs::exists(haproxy)) GTEST_SKIP() << "haproxy is not installed (scripts/setup.sh)";
  const Cluster cluster;
  const auto node = [&](const std::string& id) {
    return std::make_unique<ServerProcess>(std::vector<std::string>{
        "--cluster", cluster.config(id), "--http-port", "auto", "--metrics-port", "0",
        "--proxy-protocol-from", "127.0.0.1", "--http-trusted-proxy", "127.0.0.1"});
  };
  std::map<std::string, std::unique_ptr<ServerProcess>> nodes;
  nodes["a"] = node("a");
  nodes["b"] = node("b");
  for (const auto& entry : nodes) {  // (clang 14 does not capture structured bindings)
    const std::string& id = entry.first;
    const ServerProcess* n = entry.second.get();
    EXPECT_TRUE(eventually(
        n,
        [&] { return http_get(n->http_port(), "/healthz").find("200 OK") != std::string::npos; }))
        << "node " << id << " never said it was healthy";
  }
  // The file as documented, with these nodes' addresses and ports and no daemon lines.
  std::ifstream doc(std::string(VOXEL_SOURCE_DIR) + "/docs/haproxy-cluster.cfg");
  ASSERT_TRUE(doc) << "docs/haproxy-cluster.cfg is missing";
  const uint16_t players_port = free_port();
  uint16_t viewer_port = free_port();
  while (viewer_port == players_port) viewer_port = free_port();
  std::ostringstream config;
  for (std::string line; std::getline(doc, line);) {
    const size_t lead = line.find_first_not_of(' ');
    const std::string trimmed = lead == std::string::npos ? "" : line.substr(lead);
    if (trimmed.rfind("log ", 0) == 0 || trimmed.rfind("chroot", 0) == 0 ||
        trimmed.rfind("user ", 0) == 0 || trimmed.rfind("group ", 0) == 0 ||
        trimmed.rfind("daemon", 0) == 0 || trimmed.rfind("server ", 0) == 0)
      continue;
    if (trimmed == "bind 0.0.0.0:7777") line = "    bind 127.0.0.1:" + std::to_string(players_port);
    if (trimmed == "bind 0.0.0.0:7780") line = "    bind 127.0.0.1:" + std::to_string(viewer_port);
    config << line << "\n";
    for (const auto& [id, n] : nodes) {  // as the file's: checked, and again as backups
      if (trimmed == "backend nodes") {
        config << "    server " << id << " 127.0.0.1:" << n->port() << " send-proxy-v2 check port "
               << n->http_port() << "\n"
               << "    server " << id << "-any 127.0.0.1:" << n->port()
               << " send-proxy-v2 backup\n";
      }
      if (trimmed == "backend viewer_nodes") {
        config << "    server " << id << " 127.0.0.1:" << n->http_port() << " check\n"
               << "    server " << id << "-any 127.0.0.1:" << n->http_port() << " backup\n";
      }
    }
  }
  const fs::path cfg = cluster.tmp / "haproxy.cfg";
  std::ofstream(cfg) << config.str();
  const pid_t proxy =
      spawn_logged({haproxy, "-db", "-f", cfg.string()}, (cluster.tmp / "haproxy.log").string());
  struct Reap {
    pid_t pid;
    ~Reap() {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
  } reap{proxy};
  const auto proxy_alive = [&] { return ::waitpid(proxy, nullptr, WNOHANG) == 0; };
  const auto through_proxy = [&] {
    auto c = std::make_unique<client::Client>();
    c->connect("127.0.0.1", players_port, 5s);
    c->handshake("walker", 5s * kSlow);
    return c;
  };
  std::unique_ptr<client::Client> player;
  ASSERT_TRUE(eventually(nullptr, [&] {
    EXPECT_TRUE(proxy_alive()) << "HAProxy exited: see haproxy.log";
    try {
      player = through_proxy();
      return true;
    } catch (const std::exception&) {  // the proxy starting
      return false;
    }
  })) << "no player reached a node through HAProxy";
  // The node it reached dies.
  std::string on;
  for (const auto& [id, n] : nodes)
    if (scrape(n->metrics_port()).at("voxeld_players") == 1) on = id;
  ASSERT_FALSE(on.empty()) << "the player is on no node";
  const std::string other = on == "a" ? "b" : "a";
  const auto [x, z] = middle_of_a_zone_of(on);
  ASSERT_EQ(edit_until_accepted(*player, brush(1, x, z, 2, 4.0f)).status(),
            wire::EditResult::ACCEPTED);
  nodes.erase(on);  // kill -9
  player.reset();
  std::unique_ptr<client::Client> again;
  ASSERT_TRUE(eventually(nullptr, [&] {
    try {
      again = through_proxy();
      return true;
    } catch (const std::exception&) {
      return false;
    }
  })) << "no player reached the live node through HAProxy";
  EXPECT_EQ(scrape(nodes[other]->metrics_port()).at("voxeld_players"), 1);
  // Its health check took the dead node out (HAProxy says so on its output).
  const fs::path log = cluster.tmp / "haproxy.log";
  EXPECT_TRUE(eventually(nullptr,
                         [&] {
                           std::ifstream in(log);
                           const std::string text((std::istreambuf_iterator<char>(in)),
                                                  std::istreambuf_iterator<char>());
                           return text.find("nodes/" + on + " is DOWN") != std::string::npos;
                         }))
      << "HAProxy never marked node " << on << " down";
  const wire::EditResult r = edit_until_accepted(*again, brush(2, x + 3, z, 3, 4.0f), 30s);
  EXPECT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
  // The viewer's port reaches the live node too.
  EXPECT_TRUE(eventually(nullptr, [&] {
    return http_get(viewer_port, "/healthz").find("200 OK") != std::string::npos;
  }));
}

}  // namespace
}  // namespace vox::test
