// voxeld nodes of one cluster world (docs/CLUSTER.md) as an operator runs them: a real
// PostgreSQL and nats-server the tests start, voxeld processes with --cluster FILE, players
// speaking the protocol (tests/cluster_test_util.hpp): zones taken over, replicas, any node
// a gateway, edits across borders, a clean stop.
#include <gtest/gtest.h>
#include <signal.h>

#include <pqxx/pqxx>
#include <sstream>
#include <tuple>

#include "client-cli/commands.hpp"
#include "server/store/world_store.hpp"
#include "tests/cluster_test_util.hpp"
#include "tests/metrics_scrape.hpp"

namespace vox::test {
namespace {

TEST(ClusterNode, AKilledNodesZonesAreTakenOverWithEveryAcceptedEditAcrossTheirBorders) {
  const Cluster cluster;
  const auto edits = border_edits();
  {
    ServerProcess a({"--cluster", cluster.config("a")});
    apply_all(a, edits);
  }  // kill -9 right after the last ACCEPTED
  const Seen expected = single_node_after(edits);
  ASSERT_FALSE(expected.empty());
  ServerProcess b({"--cluster", cluster.config("b")});
  EXPECT_TRUE(eventually_seen(b, expected) == expected)
      << "the node that took the zones over does not show the edits its logs hold";
}

// Zone checkpoints (docs/CLUSTER.md): a holder writes its zones' chunks, fenced, every
// checkpoint interval. A node that joins later (taking some zones, following the others
// for its viewer) installs their checkpoints instead of applying their logs from the
// start, and so does a third after the second took the first's zones over (its first
// checkpoint writes every chunk the zones ever changed): each shows what a single node
// shows after the same edits.
TEST(ClusterNode,
     ANodeTakingOrFollowingZonesAfterTheirCheckpointsInstallsThemAndShowsTheSameWorld) {
  const Cluster cluster;
  const auto args = [&](const std::string& node) {
    return std::vector<std::string>{"--cluster", cluster.config(node),    "--metrics-port",
                                    "0",         "--checkpoint-interval", "0.2"};
  };
  const auto metric = [](const ServerProcess& p, const char* name) {
    return scrape(p.metrics_port()).at(name);
  };
  const std::vector<wire::Envelope> edits = border_edits();
  std::vector<wire::Envelope> all = edits;
  for (uint64_t i = 0; i < 4; ++i)
    all.push_back(brush(100 + i, 60.0f + 3.0f * i, 66.0f - 2.0f * i, 3, 4.0f));
  auto a = std::make_unique<ServerProcess>(args("a"));
  apply_all(*a, edits);
  ASSERT_TRUE(eventually(a.get(), [&] {
    return metric(*a, "voxeld_cluster_checkpoints_written_total") >= 4;  // the four zones
  }));
  ServerProcess b(args("b"));
  const Seen expected = single_node_after(edits);
  EXPECT_TRUE(eventually_seen(b, expected) == expected) << "b, after installing checkpoints";
  EXPECT_GE(metric(b, "voxeld_cluster_checkpoints_installed_total"), 1);
  a.reset();  // kill -9: b takes a's zones over
  apply_all(b, {all.begin() + static_cast<long>(edits.size()), all.end()});
  ASSERT_TRUE(
      eventually(&b, [&] { return metric(b, "voxeld_cluster_checkpoints_written_total") >= 4; }));
  const Seen expected_all = single_node_after(all);
  ServerProcess c(args("c"));
  EXPECT_TRUE(eventually_seen(c, expected_all) == expected_all) << "c, after b's checkpoints";
  EXPECT_GE(metric(c, "voxeld_cluster_checkpoints_installed_total"), 1);
  EXPECT_EQ(metric(b, "voxeld_cluster_checkpoints_fenced_total"), 0);
}

// Evicting a zone's chunks (docs/CLUSTER.md): a holder's changed chunks, once its zone
// checkpoints hold them, leave memory and are read back alone when a view or an edit needs
// them. After the node lost the zones (stopped past its lease while another took them,
// edited and checkpointed them), chunks read back from the successor's checkpoints would
// be ahead of its world: it installs the zones afresh instead, and shows what a single
// node shows.
TEST(ClusterNode, ChangedChunksEvictedFromHeldZonesAreReadBackAndInstalledAfreshAfterALoss) {
  const Cluster cluster;
  const auto args = [&](const std::string& node) {
    return std::vector<std::string>{"--cluster",
                                    cluster.config(node),
                                    "--metrics-port",
                                    "0",
                                    "--evict-after",
                                    "1",
                                    "--checkpoint-interval",
                                    "0.2"};
  };
  const auto metric = [](const ServerProcess& p, const char* name) {
    return scrape(p.metrics_port()).at(name);
  };
  const std::vector<wire::Envelope> edits = border_edits();
  std::vector<wire::Envelope> all = edits;
  all.push_back(brush(100, 60.0f, 66.0f, 3, 4.0f));  // on a, on chunks read back
  const size_t on_a = all.size();
  for (uint64_t i = 0; i < 3; ++i) all.push_back(explosion(200 + i, 62.0f + 2.5f * i, 65.0f));
  ServerProcess a(args("a"));
  const auto all_evicted = [&] {
    return eventually(&a, [&] {
      return metric(a, "voxeld_chunks_modified") == 0 && metric(a, "voxeld_chunks_stored") > 0;
    });
  };
  apply_all(a, edits);
  ASSERT_TRUE(all_evicted()) << "a's changed chunks stayed in memory";
  EXPECT_TRUE(world_seen(a) == single_node_after(edits)) << "a, its chunks read back";
  apply_all(a, {all.begin() + static_cast<long>(edits.size()), all.begin() + on_a});
  ASSERT_TRUE(all_evicted());
  // a stops past its lease; b takes its zones, edits them and checkpoints them.
  ::kill(a.pid(), SIGSTOP);
  ServerProcess b(args("b"));
  apply_all(b, {all.begin() + static_cast<long>(on_a), all.end()});
  const double written = metric(b, "voxeld_cluster_checkpoints_written_total");
  EXPECT_TRUE(eventually(
      &b, [&] { return metric(b, "voxeld_cluster_checkpoints_written_total") >= written + 4; }));
  ::kill(a.pid(), SIGCONT);
  const Seen expected = single_node_after(all);
  EXPECT_TRUE(eventually_seen(a, expected) == expected) << "a, after losing its zones";
  EXPECT_GE(metric(a, "voxeld_cluster_checkpoints_installed_total"), 1);
  EXPECT_TRUE(eventually_seen(b, expected) == expected) << "b";
}

// A zone no player on a node viewed for `follow_idle_s` is no longer followed there, and
// forgotten: its changed chunks leave that node's memory. Viewed again, it is installed
// afresh and shows the edits made meanwhile. A player standing still (sending no new view)
// for longer than that keeps it followed: it was forgotten under its eyes, the edits it
// saw turned back into the generated terrain (found in review).
TEST(ClusterNode, AZoneNoLongerViewedIsForgottenAndInstalledAfreshWhenViewedAgain) {
  const Cluster cluster;
  const auto [x_, z_] = middle_of_a_zone_of("a");
  const float x = x_, z = z_;
  ServerProcess a({"--cluster", cluster.config("a"), "--checkpoint-interval", "0.2"});
  ServerProcess b({"--cluster", cluster.config("b", "follow_idle_s = 1\n"), "--metrics-port", "0"});
  const auto modified = [&] { return scrape(b.metrics_port()).at("voxeld_chunks_modified"); };
  const std::vector<wire::Envelope> first = {brush(1, x, z, 4, 4.0f), explosion(2, x + 3, z)};
  const std::vector<wire::Envelope> later = {brush(3, x - 3, z + 2, 5, 4.0f)};
  const std::vector<wire::Envelope> last = {brush(4, x + 2, z - 3, 2, 4.0f)};
  apply_all(a, first);
  const Seen before = view_of(a, x, z);
  auto still = player(b, "still");
  view(*still, x, surface_y(x, z), z, 1);
  const auto sees = [&](const Seen& expected) {
    const auto deadline = std::chrono::steady_clock::now() + 20s * kSlow;
    while (std::chrono::steady_clock::now() < deadline) {
      wait_for(
          *still, [](const wire::Envelope&) { return false; }, 200ms);  // deltas applied
      if (held_by(*still) == expected) return true;
    }
    return false;
  };
  EXPECT_TRUE(sees(before)) << "b following a's zone";
  std::this_thread::sleep_for(3s);  // three times follow_idle_s, standing still
  apply_all(a, later);
  EXPECT_TRUE(sees(view_of(a, x, z))) << "b stopped following the zone of a player standing still";
  EXPECT_GT(modified(), 0);
  still.reset();
  EXPECT_TRUE(eventually(
      &b, [&] { return modified() == 0; }, 20s))
      << "b kept the changed chunks of a zone nobody views there";
  apply_all(a, last);
  const Seen expected = view_of(a, x, z);
  EXPECT_TRUE(eventually(&b, [&] { return view_of(b, x, z) == expected; }))
      << "b, viewing it again";
}

// A zone checkpoint whose chunks do not decode (a damaged row): the node taking the zone
// applies the zone's log instead, and shows what a single node shows.
TEST(ClusterNode, ANodeWhoseZoneCheckpointDoesNotDecodeAppliesTheLogInstead) {
  const Cluster cluster;
  const std::vector<wire::Envelope> edits = border_edits();
  {
    ServerProcess a(
        {"--cluster", cluster.config("a"), "--metrics-port", "0", "--checkpoint-interval", "0.2"});
    apply_all(a, edits);
    ASSERT_TRUE(eventually(&a, [&] {
      return scrape(a.metrics_port()).at("voxeld_cluster_checkpoints_written_total") >= 4;
    }));
  }  // kill -9
  {
    pqxx::connection c(cluster.database);
    pqxx::work t(c);
    EXPECT_GT(t.exec("UPDATE zone_chunks SET samples = '\\x0102'::bytea").affected_rows(), 0);
    t.commit();
  }
  ServerProcess b({"--cluster", cluster.config("b"), "--metrics-port", "0"});
  const Seen expected = single_node_after(edits);
  EXPECT_TRUE(eventually_seen(b, expected) == expected);
  // Only a zone whose records changed no chunk has a checkpoint left that installs.
  EXPECT_LT(scrape(b.metrics_port()).at("voxeld_cluster_checkpoints_installed_total"), 4);
}

// Moving in (docs/CLUSTER.md): a single node's world (its log's tail not checkpointed: the
// node was killed) migrated into an empty cluster database is what a cluster node shows;
// after more edits there the cluster world verifies, and migrated back out it is a single
// node's world showing what a single node shows after every edit.
TEST(ClusterNode, AWorldMigratedIntoAClusterAndBackShowsWhatASingleNodeShows) {
  const Cluster cluster;
  const TempDir dir("migrate");
  const std::string single = (dir.path() / "single").string(),
                    back = (dir.path() / "back").string();
  const std::vector<wire::Envelope> edits = border_edits();
  std::vector<wire::Envelope> all = edits;
  for (uint64_t i = 0; i < 3; ++i)
    all.push_back(explosion(200 + i, 61.0f + 2.5f * i, 67.0f - 3.0f * i));
  {
    // An admin's world (--open-role admin) with a protected region, far from the edits.
    ServerProcess s({"--world", single, "--open-role", "admin"});
    apply_all(s, edits);
    auto admin = player(s, "admin");
    wire::Envelope add;
    add.mutable_region_command()->set_request_id(9);
    auto* r = add.mutable_region_command()->mutable_add();
    r->set_name("far");
    auto* b = r->mutable_box();
    b->set_min_x(1000), b->set_min_y(0), b->set_min_z(1000);
    b->set_max_x(1010), b->set_max_y(10), b->set_max_z(1010);
    r->set_protect_build(true);
    admin->send(add);
    const auto added =
        wait_for(*admin, [](const wire::Envelope& m) { return m.has_region_result(); });
    ASSERT_TRUE(added.has_value());
    ASSERT_EQ(added->region_result().status(), wire::RegionResult::OK)
        << added->region_result().reason();
  }  // kill -9
  const auto cli = [](const std::vector<std::string>& args) {
    std::ostringstream out, err;
    const int code = cli::run_cli(args, out, err);
    return std::make_tuple(code, out.str(), err.str());
  };
  const auto [in_code, in_out, in_err] =
      cli({"world", "migrate", "--from", single, "--to", cluster.database, "--name", "test",
           "--zone-chunks", std::to_string(kZoneChunks)});
  ASSERT_EQ(in_code, 0) << in_out << in_err;
  EXPECT_NE(in_out.find("1 protected regions"), std::string::npos) << in_out;
  {
    store::ZoneLeases db(cluster.database, "test-reader", 30s);
    const store::ZoneRegions regions = db.read_regions();
    ASSERT_EQ(regions.table.regions.size(), 1u);
    EXPECT_EQ(regions.table.regions[0].name, "far");
  }
  // Into a cluster world that has records: refused.
  ServerProcess a({"--cluster", cluster.config("a")});
  const Seen expected = single_node_after(edits);
  EXPECT_TRUE(eventually_seen(a, expected) == expected) << "the migrated world on a cluster node";
  apply_all(a, {all.begin() + static_cast<long>(edits.size()), all.end()});
  EXPECT_EQ(a.terminate(), 0);
  const auto [again_code, again_out, again_err] =
      cli({"world", "migrate", "--from", single, "--to", cluster.database, "--name", "test",
           "--zone-chunks", std::to_string(kZoneChunks)});
  EXPECT_EQ(again_code, 1);
  EXPECT_NE(again_err.find("has records already"), std::string::npos) << again_err;
  const auto [v_code, v_out, v_err] = cli({"world", "verify", cluster.database});
  EXPECT_EQ(v_code, 0) << v_out << v_err;
  EXPECT_NE(v_out.find("all match"), std::string::npos) << v_out;
  const auto [out_code, out_out, out_err] =
      cli({"world", "migrate", "--from", cluster.database, "--to", back});
  ASSERT_EQ(out_code, 0) << out_out << out_err;
  const auto [bv_code, bv_out, bv_err] = cli({"world", "verify", back});
  EXPECT_EQ(bv_code, 0) << bv_out << bv_err;
  {
    const store::RegionTable regions =
        store::open_world_store(back, {.read_only = true})->read_regions();
    ASSERT_EQ(regions.regions.size(), 1u) << "the protected region did not come back out";
    EXPECT_EQ(regions.regions[0].name, "far");
  }
  ServerProcess b({"--world", back});
  EXPECT_TRUE(world_seen(b) == single_node_after(all)) << "the world migrated back out";
  // One zone alone: its chunks as the whole world has them, and nothing else.
  const std::string one = (dir.path() / "one").string();
  const world::ZoneId zone{1, 1};
  const auto [one_code, one_out, one_err] =
      cli({"world", "migrate", "--from", cluster.database, "--to", one, "--zone", "1,1"});
  ASSERT_EQ(one_code, 0) << one_out << one_err;
  EXPECT_EQ(std::get<0>(cli({"world", "migrate", "--from", cluster.database, "--to", one + "2",
                             "--zone", "7,7"})),
            1);  // no such zone
  EXPECT_EQ(std::get<0>(cli({"world", "migrate", "--from", cluster.database, "--to", one + "3",
                             "--zone", "1;1"})),
            2);  // not X,Z
  auto whole = store::open_world_store(back, {.read_only = true});
  auto alone = store::open_world_store(one, {.read_only = true});
  size_t in_zone = 0;
  whole->for_each_chunk([&](world::ChunkCoord c, uint64_t) {
    const auto copy = alone->read_chunk(c);
    if (world::zone_of(c, kZoneChunks) != zone) {
      EXPECT_FALSE(copy.has_value()) << "a chunk of another zone was migrated";
      return;
    }
    ++in_zone;
    EXPECT_TRUE(copy.has_value() && store::read_checkpointed_chunk(*alone, c) ==
                                        store::read_checkpointed_chunk(*whole, c));
  });
  EXPECT_GT(in_zone, 0u);
}

// Replicas: a viewer on another node sees the owner's edits as they are committed, and
// its view (meshed on its own node) equals a single node's after the same edits.
TEST(ClusterNode, AViewerOnAnotherNodeSeesTheOwnersEditsAsTheyAreCommitted) {
  const Cluster cluster;
  const auto [x_, z_] = middle_of_a_zone_of("a");
  const float x = x_, z = z_;
  const std::vector<wire::Envelope> edits = {brush(1, x, z, 4, 5.0f), explosion(2, x + 4, z - 3),
                                             smooth(3, x - 2, z + 2), brush(4, x, z + 5, 2, 3.0f)};
  ServerProcess a({"--cluster", cluster.config("a")});
  ServerProcess b({"--cluster", cluster.config("b")});
  // The viewer on b first: b follows the zone before the edits.
  auto viewer = player(b, "viewer");
  view(*viewer, x, surface_y(x, z), z, 1);
  const Seen before = held_by(*viewer);
  apply_all(a, edits);
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  auto fresh_viewer = player(fresh, "viewer");
  view(*fresh_viewer, x, surface_y(x, z), z, 1);
  const Seen expected = held_by(*fresh_viewer);
  Seen live;
  const auto deadline = std::chrono::steady_clock::now() + 20s * kSlow;
  while (std::chrono::steady_clock::now() < deadline) {
    wait_for(
        *viewer, [](const wire::Envelope&) { return false; }, 200ms);  // deltas applied
    live = held_by(*viewer);
    if (live == expected) break;
  }
  EXPECT_FALSE(before == expected);
  EXPECT_TRUE(live == expected) << "the viewer on b does not see a's edits";
}

// Any node is a gateway: an edit sent to a node that does not hold its zone goes to the
// node that does (taken on first use by the node that ranks first), and viewers on both
// nodes see the world a single node would show.
TEST(ClusterNode, AnEditSentToAnyNodeIsAppliedByTheZonesHolderAndSeenOnEveryNode) {
  const Cluster cluster;
  const std::pair<float, float> pa = middle_of_a_zone_of("a"), pb = middle_of_a_zone_of("b");
  const float ax = pa.first, az = pa.second, bx = pb.first, bz = pb.second;
  const std::vector<wire::Envelope> in_a = {brush(1, ax, az, 4, 5.0f), explosion(2, ax + 3, az)};
  const std::vector<wire::Envelope> in_b = {brush(3, bx, bz, 2, 5.0f), smooth(4, bx + 1, bz)};
  ServerProcess a({"--cluster", cluster.config("a")});
  ServerProcess b({"--cluster", cluster.config("b")});
  apply_all(b, in_a);  // b forwards them to a
  apply_all(a, in_b);  // and a to b
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, in_a);
  apply_all(fresh, in_b);
  const Seen expect_a = view_of(fresh, ax, az), expect_b = view_of(fresh, bx, bz);
  for (const ServerProcess* node : {&a, &b}) {
    EXPECT_TRUE(eventually(node, [&] { return view_of(*node, ax, az) == expect_a; }))
        << "a's zone differs on node " << (node == &a ? "a" : "b");
    EXPECT_TRUE(eventually(node, [&] { return view_of(*node, bx, bz) == expect_b; }))
        << "b's zone differs on node " << (node == &a ? "a" : "b");
  }
}

// A node stopped (SIGTERM) while it follows zones, whose records keep arriving, and while it
// holds zones: it hands them off and exits 0 (its followers were stopped before the
// pipeline they wake went away).
TEST(ClusterNode, ANodeFollowingAndHoldingZonesStopsCleanlyOnSigterm) {
  const Cluster cluster;
  const auto [x_, z_] = middle_of_a_zone_of("a");
  const float x = x_, z = z_;
  const auto [bx_, bz_] = middle_of_a_zone_of("b");
  ServerProcess a({"--cluster", cluster.config("a")});
  ServerProcess b({"--cluster", cluster.config("b")});
  auto viewer = player(b, "viewer");
  view(*viewer, x, surface_y(x, z), z, 1);
  auto editor = player(a, "editor");
  ASSERT_EQ(edit_until_accepted(*editor, brush(1, bx_, bz_, 2, 3)).status(),
            wire::EditResult::ACCEPTED);  // b holds its zone (a forwarded it)
  std::atomic<bool> stop{false};
  std::thread edits([&] {
    for (uint64_t i = 2; !stop; ++i)
      edit_and_wait(*editor, brush(i, x, z, static_cast<int>(1 + i % 4), 3), 2s);
  });
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(b.terminate(), 0) << "b did not stop cleanly (see its log)";
  stop = true;
  edits.join();
  // b handed its zone on as it stopped: a takes it and edits there go on.
  EXPECT_EQ(edit_until_accepted(*editor, brush(1000, bx_, bz_ + 3, 3, 3)).status(),
            wire::EditResult::ACCEPTED);
  EXPECT_EQ(a.terminate(), 0);
}

// An edit across zones held by different nodes: one part per zone, each applied and logged
// by its zone's holder; the player is answered once; both nodes show what a single node
// shows after the same edits, across two and four zones.
TEST(ClusterNode, AnEditAcrossZonesHeldByDifferentNodesIsAppliedByEachHolder) {
  const Cluster cluster;
  const ZonesApart apart = zones_held_apart();
  const float bx = apart.border_x(), z = apart.middle_z();
  const std::vector<wire::Envelope> edits = {
      brush(1, bx - 1.5f, z, 4, 6.0f), explosion(2, bx + 1.0f, z + 5.0f),
      brush(3, bx + 0.5f, 0.5f, 2, 6.0f),  // four zones: the z = 0 border too
      explosion(4, bx - 2.0f, 1.0f), brush(5, bx, z - 4.0f, 5, 3.0f)};
  ServerProcess a({"--cluster", cluster.config("a"), "--metrics-port", "0"});
  ServerProcess b({"--cluster", cluster.config("b")});
  auto on_a = player(a, "editor-a");
  auto on_b = player(b, "editor-b");
  for (size_t i = 0; i < edits.size(); ++i) {
    client::Client& c = i % 2 == 0 ? *on_a : *on_b;
    const wire::EditResult r = edit_until_accepted(c, edits[i]);
    EXPECT_EQ(r.status(), wire::EditResult::ACCEPTED) << "edit " << i + 1 << ": " << r.reason();
  }
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  for (const float at_z : {z, 0.5f}) {
    const Seen expected = view_of(fresh, bx, at_z);
    for (const ServerProcess* node : {&a, &b}) {
      // A view's edge chunks read a voxel of zones it does not show: the node follows
      // those too (the halo), or their meshes there stay stale.
      EXPECT_TRUE(eventually(node, [&] { return view_of(*node, bx, at_z) == expected; }))
          << "the border at z = " << at_z << " differs on node " << (node == &a ? "a" : "b");
    }
  }
  EXPECT_GE(scrape(a.metrics_port()).at("voxeld_cluster_edits_split_total"), 1);
  // Every part in its zone's log once.
  const std::vector<world::ZoneId> zones = {
      apart.of_a, apart.of_b, {apart.of_a.x, -1}, {apart.of_b.x, -1}};
  const auto logged = edit_ids_logged(cluster.database, zones);
  EXPECT_FALSE(logged.empty()) << "no edit was split";
  for (const auto& [where, n] : logged)
    EXPECT_EQ(n, 1) << "edit " << where.second << " logged " << n << " times in zone ("
                    << where.first.x << ", " << where.first.z << ")";
}

// The harness with all three nodes alive: players on a, b and c edit inside each
// of four zones held by the three nodes, across the borders of two and at the corner of
// all four; each node shows what a single node shows after the same edits (views across
// the nodes' borders closed), and every edit's part is in its zone's log once.
TEST(ClusterNode, EditsInOneAcrossTwoAndAcrossFourZonesOfThreeNodesShowWhatASingleNodeShows) {
  const Cluster cluster;
  const std::optional<CornerOfThree> corner = corner_of_three();
  ASSERT_TRUE(corner.has_value());
  const float cx = corner->corner(corner->low.x), cz = corner->corner(corner->low.z);
  const float half = 0.5f * kZoneChunks * world::kChunkSize;  // a zone's middle from its edge
  uint64_t id = 1;
  std::vector<wire::Envelope> edits;
  for (const float dx : {-half, half})  // inside each zone
    for (const float dz : {-half, half}) edits.push_back(brush(id++, cx + dx, cz + dz, 3, 5.0f));
  edits.push_back(brush(id++, cx, cz - half, 4, 5.0f));  // across two: the x border
  edits.push_back(explosion(id++, cx + 1.0f, cz + half));
  edits.push_back(brush(id++, cx - half, cz, 2, 5.0f));         // across two: the z border
  edits.push_back(brush(id++, cx + 0.5f, cz - 0.5f, 5, 6.0f));  // across four
  edits.push_back(explosion(id++, cx - 1.0f, cz + 1.5f));
  ServerProcess a({"--cluster", cluster.config("a"), "--metrics-port", "0"});
  ServerProcess b({"--cluster", cluster.config("b"), "--metrics-port", "0"});
  ServerProcess c({"--cluster", cluster.config("c"), "--metrics-port", "0"});
  std::vector<std::unique_ptr<client::Client>> players;
  players.push_back(player(a, "editor-a"));
  players.push_back(player(b, "editor-b"));
  players.push_back(player(c, "editor-c"));
  for (size_t i = 0; i < edits.size(); ++i) {
    const wire::EditResult r = edit_until_accepted(*players[i % 3], edits[i]);
    EXPECT_EQ(r.status(), wire::EditResult::ACCEPTED) << "edit " << i + 1 << ": " << r.reason();
  }
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  const Seen expected = view_of(fresh, cx, cz);
  for (const ServerProcess* node : {&a, &b, &c}) {
    EXPECT_TRUE(eventually(node, [&] { return view_of(*node, cx, cz) == expected; }))
        << "the corner differs on node "
        << (node == &a   ? "a"
            : node == &b ? "b"
                         : "c");
  }
  double split = 0;
  for (const ServerProcess* node : {&a, &b, &c})
    split += scrape(node->metrics_port()).at("voxeld_cluster_edits_split_total");
  EXPECT_GE(split, 3) << "the edits across borders were not split between holders";
  const auto logged = edit_ids_logged(cluster.database, corner->zones());
  EXPECT_FALSE(logged.empty()) << "no edit was forwarded or split";
  for (const auto& [where, n] : logged) {
    EXPECT_EQ(n, 1) << "edit " << where.second << " logged " << n << " times in zone ("
                    << where.first.x << ", " << where.first.z << ")";
  }
}

// A smooth across a zone border (docs/CLUSTER.md): each zone's part reads only its own
// zone's samples, so it replays from that zone's log alone. Smooths split over two nodes,
// and one applied whole by a node holding both zones, are seen alike on both nodes and by
// a third node that replays the logs after both are gone. (It was refused before.)
TEST(ClusterNode, ASmoothAcrossZonesReplaysFromEachZonesLogAlone) {
  const Cluster cluster;
  const ZonesApart apart = zones_held_apart();
  const float bx = apart.border_x(), z = apart.middle_z();
  const std::vector<wire::Envelope> edits = {brush(1, bx - 3.0f, z, 4, 5.0f),
                                             brush(2, bx + 3.0f, z + 2.0f, 2, 5.0f),
                                             smooth(3, bx, z), smooth(4, bx + 1.0f, z + 3.0f)};
  Seen seen;
  {
    ServerProcess a({"--cluster", cluster.config("a")});
    ServerProcess b({"--cluster", cluster.config("b")});
    auto on_a = player(a, "editor-a");
    auto on_b = player(b, "editor-b");
    for (size_t i = 0; i < edits.size(); ++i) {
      const wire::EditResult r = edit_until_accepted(i % 2 ? *on_b : *on_a, edits[i]);
      ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << "edit " << i + 1 << ": " << r.reason();
    }
    // Each node follows the other's zone once a viewer looks: then both show the same.
    EXPECT_TRUE(eventually(&b, [&] {
      seen = view_of(a, bx, z);
      return view_of(b, bx, z) == seen;
    })) << "the two nodes show the smooths differently";
  }  // both killed
  ServerProcess c({"--cluster", cluster.config("c")});
  EXPECT_TRUE(eventually(&c, [&] { return view_of(c, bx, z) == seen; }))
      << "a replay of the zones' logs differs from what the nodes showed";
  // One node holding both zones applies a smooth across them whole: the same again.
  auto on_c = player(c, "editor-c");
  ASSERT_EQ(edit_until_accepted(*on_c, smooth(5, bx - 1.0f, z - 2.0f)).status(),
            wire::EditResult::ACCEPTED);
  const Seen after = view_of(c, bx, z);
  EXPECT_FALSE(after == seen);
  c.terminate();
  ServerProcess d({"--cluster", cluster.config("d")});
  EXPECT_TRUE(eventually(&d, [&] { return view_of(d, bx, z) == after; }))
      << "a whole smooth's parts do not replay to what it did";
}

}  // namespace
}  // namespace vox::test
