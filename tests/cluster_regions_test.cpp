// Protected regions in a cluster world (docs/CLUSTER.md, "Protected regions"): one table in
// the cluster's database, changed through any node, holding for edits on every node as
// they hold on a single node (docs/PROTOCOL.md 4.9). Real processes over a real PostgreSQL
// and nats-server (tests/cluster_test_util.hpp), players with signed tokens.
#include <gtest/gtest.h>

#include <pqxx/pqxx>

#include "server/auth/player_token.hpp"
#include "tests/cluster_test_util.hpp"

namespace vox::test {
namespace {

int64_t unix_now() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A border between a zone node a holds and one node b holds, among {a, b}: its voxel x
// (the zones' row z = 0 spans voxels 0 .. 63).
float border_from_a_to_b() {
  const std::vector<std::string> nodes = {"a", "b"};
  for (int32_t x = 0; x < 64; ++x) {
    if (nodes[*world::first_ranked({x, 0}, nodes)] == "a" &&
        nodes[*world::first_ranked({x + 1, 0}, nodes)] == "b")
      return static_cast<float>((x + 1) * kZoneChunks * world::kChunkSize);
  }
  ADD_FAILURE() << "no zone of a next to one of b";
  return 0;
}

wire::Envelope region_command(uint64_t request) {
  wire::Envelope m;
  m.mutable_region_command()->set_request_id(request);
  return m;
}

// Protects the samples within 10 voxels of x (in x) and of z = 32, from 8 below the
// ground at (x, 32) to 4 above it, against building and explosions; alice owns it.
wire::Envelope add_region(uint64_t request, float x) {
  wire::Envelope m = region_command(request);
  auto* r = m.mutable_region_command()->mutable_add();
  r->set_name("market");
  const int ix = static_cast<int>(x), iy = static_cast<int>(surface_y(x, 32));
  auto* b = r->mutable_box();
  b->set_min_x(ix - 10), b->set_min_y(iy - 8), b->set_min_z(22);
  b->set_max_x(ix + 10), b->set_max_y(iy + 4), b->set_max_z(42);
  r->set_protect_build(true), r->set_protect_explode(true);
  r->add_owners("alice");
  return m;
}

// A box stamp digging x - 4 .. x + 4 around the ground at (x, 32): inside the region.
wire::Envelope dig_inside(uint64_t request, float x) {
  wire::Envelope m;
  m.mutable_edit()->set_request_id(request);
  auto* s = m.mutable_edit()->mutable_stamp();
  const float y = surface_y(x, 32);
  s->set_shape(wire::Stamp::BOX);
  s->mutable_min()->set_x(x - 4), s->mutable_min()->set_y(y - 4), s->mutable_min()->set_z(28);
  s->mutable_max()->set_x(x + 4), s->mutable_max()->set_y(y), s->mutable_max()->set_z(36);
  s->set_solid(false);
  return m;
}

wire::RegionResult ask_region(client::Client& c, const wire::Envelope& command) {
  c.send(command);
  const auto r = wait_for(c, [&](const wire::Envelope& m) {
    return m.has_region_result() &&
           m.region_result().request_id() == command.region_command().request_id();
  });
  return r ? r->region_result() : wire::RegionResult();
}

// Writes a region straight into the cluster's database (as another node's change whose
// message never came): protecting x - 10 .. x + 10 around the ground at (x, 32), z 22 .. 42.
void write_region_row(const std::string& database, uint64_t id, float x) {
  pqxx::connection c(database);
  pqxx::work t(c);
  const int ix = static_cast<int>(x), iy = static_cast<int>(surface_y(x, 32));
  t.exec_params(
      "INSERT INTO zone_regions (id, name, x0, y0, z0, x1, y1, z1, flags, owners, created_by, "
      "created_ms) VALUES ($1, 'quiet', $2, $3, 22, $4, $5, 42, 3, 'alice', 'root', 0)",
      static_cast<int64_t>(id), ix - 10, iy - 8, ix + 10, iy + 4);
  t.exec_params(
      "UPDATE cluster_world SET regions_version = regions_version + 1, next_region_id = $1",
      static_cast<int64_t>(id + 1));
  t.commit();
}

class ClusterRegions : public ::testing::Test {
 protected:
  ClusterRegions() { std::ofstream(keys_ / "game.pub") << auth::key_to_text(key_.public_key); }
  std::vector<std::string> node(const std::string& id) const {
    return {"--cluster", cluster_.config(id), "--auth-public-key", (keys_ / "game.pub").string()};
  }
  std::vector<std::string> single() const {
    return {"--in-memory", "--auth-public-key", (keys_ / "game.pub").string()};
  }
  std::unique_ptr<client::Client> join(const ServerProcess& server, const std::string& id,
                                       auth::Role role = auth::Role::kPlayer) const {
    auto c = connect_to(server);
    c->handshake(id, 5s * kSlow,
                 auth::mint_token({.player_id = id,
                                   .display_name = id,
                                   .role = role,
                                   .expires_at = unix_now() + 600,
                                   .edit_rate = 0,
                                   .edit_burst = 0},
                                  key_.seed));
    return c;
  }
  Seen view_around(const ServerProcess& server, float x) const {
    auto viewer = join(server, "viewer", auth::Role::kViewer);
    view(*viewer, x, surface_y(x, 32), 32, 1);
    return held_by(*viewer);
  }

  const Cluster cluster_;
  const TempDir keys_{"keys"};
  const auth::KeyPair key_ = auth::generate_key_pair();
};

// An admin on one node adds a region across the border of a zone node a holds and one node
// b holds. Players on either node are clipped by it, or refused inside it, by whichever
// node holds the samples (the region reached it over the cluster); its owner is not. Every
// node lists it, a node started later too, and both show what a single node shows after
// the same commands. Once it is removed, edits inside it pass.
TEST_F(ClusterRegions, ARegionAddedOnOneNodeHoldsForEditsOnEveryNode) {
  const float border = border_from_a_to_b();
  // What the players do, through `admin_node` and `a`, `b`: results checked as they come.
  const auto play = [&](const ServerProcess& a, const ServerProcess& b) {
    auto admin = join(b, "root", auth::Role::kAdmin);
    auto mallory_a = join(a, "mallory"), mallory_b = join(b, "mallet"), alice = join(a, "alice");
    // Both zones taken first (an edit in each, far from the region).
    for (const float x : {border - 28, border + 28}) {
      const wire::EditResult r = edit_until_accepted(*alice, brush(1, x, 32, 2, 3.0f));
      ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
    }
    const wire::RegionResult added = ask_region(*admin, add_region(5, border));
    ASSERT_EQ(added.status(), wire::RegionResult::OK) << added.reason();
    ASSERT_EQ(added.regions_size(), 1);
    const uint64_t id = added.regions(0).id();
    // Explosions next to it, from either node, in either zone: clipped, never accepted whole
    // (an edit applied by a table the region had not reached is refused and sent again).
    int request = 10;
    for (const auto& [c, x] :
         {std::pair{mallory_a.get(), border - 14}, std::pair{mallory_b.get(), border + 14},
          std::pair{mallory_a.get(), border + 14}}) {
      const wire::EditResult r = edit_until_accepted(*c, explosion(request++, x, 32));
      ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
      ASSERT_EQ(r.clipped_by_size(), 1) << "an explosion at x " << x << " was not clipped";
      EXPECT_EQ(r.clipped_by(0), id);
    }
    for (client::Client* c : {mallory_a.get(), mallory_b.get()}) {
      const wire::EditResult r = edit_until_accepted(*c, dig_inside(request++, border));
      EXPECT_EQ(r.status(), wire::EditResult::FORBIDDEN) << r.reason();
    }
    const wire::EditResult owned = edit_until_accepted(*alice, dig_inside(request++, border - 3));
    EXPECT_EQ(owned.status(), wire::EditResult::ACCEPTED) << owned.reason();
    EXPECT_EQ(owned.clipped_by_size(), 0);
  };

  ServerProcess a(node("a")), b(node("b"));
  play(a, b);
  ServerProcess fresh(single());
  play(fresh, fresh);
  const Seen expected = view_around(fresh, border);
  for (const ServerProcess* n : {&a, &b}) {
    EXPECT_TRUE(eventually(n, [&] { return view_around(*n, border) == expected; }))
        << "node " << (n == &a ? "a" : "b") << " differs from a single node";
  }
  // Every node lists it: a (which heard of it) and c, started after it was added.
  ServerProcess c(node("c"));
  for (const ServerProcess* n : {&a, &c}) {
    auto admin = join(*n, "root", auth::Role::kAdmin);
    wire::Envelope list = region_command(20);
    list.mutable_region_command()->mutable_list();
    EXPECT_TRUE(eventually(n,
                           [&] {
                             const wire::RegionResult r = ask_region(*admin, list);
                             return r.regions_size() == 1 && r.regions(0).name() == "market";
                           }))
        << "node " << (n == &a ? "a" : "c") << " does not list the region";
  }
  // Removed through a: a player's dig inside it passes on b, once b heard of it (until
  // then b may refuse it FORBIDDEN by the table it has: a refusal is not checked against
  // the cluster's, docs/CLUSTER.md).
  auto admin = join(a, "root", auth::Role::kAdmin);
  wire::Envelope remove = region_command(21);
  remove.mutable_region_command()->set_remove(1);
  const wire::RegionResult removed = ask_region(*admin, remove);
  EXPECT_EQ(removed.status(), wire::RegionResult::OK) << removed.reason();
  auto mallet = join(b, "mallet");
  wire::EditResult r;
  uint64_t request = 30;
  EXPECT_TRUE(eventually(&b, [&] {
    r = edit_until_accepted(*mallet, dig_inside(request++, border + 3));
    return r.status() == wire::EditResult::ACCEPTED;
  })) << r.reason();
  EXPECT_EQ(r.clipped_by_size(), 0);
}

// A region change this node never heard of (its NATS message lost: here the row is written
// straight into the database) still holds for its edits: one clipped by the table before
// is refused when appended (no zone lost), the node reads the table again, and the edit
// sent again is clipped. Never is an edit accepted whole inside the region.
TEST_F(ClusterRegions, ARegionChangeANodeNeverHeardOfStillHoldsForItsEdits) {
  const float border = border_from_a_to_b(), at = border + 40;
  ServerProcess a(node("a")), b(node("b"));
  auto mallet = join(b, "mallet");
  const wire::EditResult taken = edit_until_accepted(*mallet, brush(1, border + 10, 32, 2, 3.0f));
  ASSERT_EQ(taken.status(), wire::EditResult::ACCEPTED) << taken.reason();
  write_region_row(cluster_.database, 7, at);
  const auto first = edit_and_wait(*mallet, explosion(2, at - 14, 32));
  ASSERT_TRUE(first.has_value());
  if (first->edit_result().status() == wire::EditResult::ACCEPTED) {  // b polled first
    EXPECT_EQ(first->edit_result().clipped_by_size(), 1) << "accepted whole inside the region";
  } else {
    EXPECT_EQ(first->edit_result().status(), wire::EditResult::STORAGE_UNAVAILABLE)
        << first->edit_result().reason();
  }
  const wire::EditResult again = edit_until_accepted(*mallet, explosion(3, at - 14, 32));
  ASSERT_EQ(again.status(), wire::EditResult::ACCEPTED) << again.reason();
  ASSERT_EQ(again.clipped_by_size(), 1);
  EXPECT_EQ(again.clipped_by(0), 7u);
  // The next region added through a gets the next id.
  auto admin = join(a, "root", auth::Role::kAdmin);
  const wire::RegionResult added = ask_region(*admin, add_region(4, border - 30));
  ASSERT_EQ(added.status(), wire::RegionResult::OK) << added.reason();
  EXPECT_EQ(added.regions(0).id(), 8u);
}

// A part of an edit across zones that another zone's holder logged, and left pending for
// this zone (its own request never came), is completed as that holder clipped it: the
// edit was accepted, so a region added since (here covering all of it, which would refuse
// the edit now) neither refuses nor clips it again. (It was refused, and tried again
// every 2 s for ever.)
TEST_F(ClusterRegions, APendingPartIsCompletedAsItsLoggerClippedItThoughARegionNowCoversIt) {
  ServerProcess b(node("b"));  // alone: it takes every zone it is asked for
  auto mallet = join(b, "mallet");
  const world::ZoneId mine{1, 0}, other{2, 0};  // the border between them at x = 128
  const wire::EditResult taken = edit_until_accepted(*mallet, brush(1, 96, 32, 2, 3.0f));
  ASSERT_EQ(taken.status(), wire::EditResult::ACCEPTED) << taken.reason();
  // A "node" that holds the other zone logs its part of a dig across the border, with the
  // part for b's zone pending.
  store::ZoneLeases logger(cluster_.database, "logger", 30s);
  const uint64_t epoch = *logger.acquire(other);
  const wire::Envelope dig = dig_inside(2, 128);
  store::LoggedEdit part;
  part.edit = *net::edit_from_wire(dig.edit()).edit;
  part.author = "mallory";
  part.edit_id = 424242;
  part.unix_ms = 1;
  const world::VoxelBox box = world::touched_box(part.edit);
  store::LoggedEdit own = part;
  own.keep = world::outside_zone(box, other, kZoneChunks);
  part.keep = world::outside_zone(box, mine, kZoneChunks);
  const std::vector<store::ZoneRecord> record = {
      {1, 1, store::encode_zone_edit(own), part.edit_id}};
  const std::vector<store::ZonePending> pending = {
      {mine, part.edit_id, 1, store::encode_zone_edit(part)}};
  logger.append(std::vector<store::ZoneAppend>{{other, epoch, record, pending}});
  write_region_row(cluster_.database, 1, 128);  // the dig lies wholly inside it now
  const auto completed = [&] {
    for (const store::ZoneRecord& r : logger.read_log(mine, 0))
      if (r.edit_id == part.edit_id) return true;
    return false;
  };
  EXPECT_TRUE(eventually(&b, completed, 20s)) << "the pending part was never completed";
  const std::vector<world::ZoneId> zones = {mine};
  EXPECT_TRUE(logger.read_pending(zones, 0ms).empty());
}

// A pending part that can never be applied (a damaged row that still decodes, here into a
// brush over the radius limit) is removed with an error, not tried every 2 s for ever.
TEST_F(ClusterRegions, APendingPartThatCanNeverBeAppliedIsRemoved) {
  ServerProcess b(node("b"));
  auto mallet = join(b, "mallet");
  const world::ZoneId mine{1, 0}, other{2, 0};
  const wire::EditResult taken = edit_until_accepted(*mallet, brush(1, 96, 32, 2, 3.0f));
  ASSERT_EQ(taken.status(), wire::EditResult::ACCEPTED) << taken.reason();
  store::ZoneLeases logger(cluster_.database, "logger", 30s);
  const uint64_t epoch = *logger.acquire(other);
  store::LoggedEdit part;
  part.edit = *net::edit_from_wire(brush(2, 126, 32, 2, 3.0f).edit()).edit;
  std::get<world::Brush>(part.edit).radius = 1000;  // no server takes it
  part.edit_id = 777;
  const std::vector<store::ZoneRecord> record = {{1, 1, store::encode_zone_edit(part), 777}};
  const std::vector<store::ZonePending> pending = {{mine, 777, 1, store::encode_zone_edit(part)}};
  logger.append(std::vector<store::ZoneAppend>{{other, epoch, record, pending}});
  const std::vector<world::ZoneId> zones = {mine};
  EXPECT_TRUE(eventually(
      &b, [&] { return logger.read_pending(zones, 0ms).empty(); }, 20s))
      << "the part is still pending";
  for (const store::ZoneRecord& r : logger.read_log(mine, 0)) EXPECT_NE(r.edit_id, 777u);
}

}  // namespace
}  // namespace vox::test
