// Identity against a real voxeld started with --auth-public-key: a token the backend
// signed lets a player in under its name and role; a missing, malformed, foreign,
// altered or expired one is refused with its own Error and the connection closes; a
// second connection of a player replaces the first; a viewer may not edit; edits are
// logged under their author's player id. Only an admin manages protected regions; a
// player's explosion from outside one is clipped and a stamp inside it refused; regions
// survive a restart; a player's edit budget is shared by its connections.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "client-cli/commands.hpp"
#include "client/voxel_client.hpp"
#include "server/auth/player_token.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/server_process.hpp"
#include "tests/temp_dir.hpp"
#include "tests/token_world.hpp"

namespace vox {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using client::Client;

class Identity : public test::TokenWorld {
 protected:
  Identity() : TokenWorld("identity") {}

  std::vector<std::string> server_args() const {
    std::vector<std::string> args = key_and_world();
    args.push_back("--keep-log");
    return args;
  }
  // Sends `m` and returns the answer with the same request id (EditResult or RegionResult).
  static wire::Envelope ask(Client& c, const wire::Envelope& m) {
    c.send(m);
    for (;;) {
      auto r = c.receive(20s);
      if (!r) return {};
      if (r->has_edit_result() || r->has_region_result() || r->has_error()) return *r;
    }
  }
  static wire::Envelope explosion_at(float x, float y, float z, float radius, uint64_t request) {
    wire::Envelope m;
    m.mutable_edit()->set_request_id(request);
    auto* e = m.mutable_edit()->mutable_explosion();
    e->mutable_center()->set_x(x), e->mutable_center()->set_y(y), e->mutable_center()->set_z(z);
    e->set_radius(radius);
    e->set_power(2);
    return m;
  }
  static wire::Envelope list_regions() {
    wire::Envelope m;
    m.mutable_region_command()->set_request_id(7);
    m.mutable_region_command()->mutable_list();
    return m;
  }
  static wire::EditResult explode(Client& c, uint64_t request, float y) {
    wire::Envelope m;
    m.mutable_edit()->set_request_id(request);
    auto* x = m.mutable_edit()->mutable_explosion();
    x->mutable_center()->set_y(y);
    x->set_radius(3);
    x->set_power(1);
    c.send(m);
    for (;;) {
      auto r = c.receive(20s);
      if (!r) return {};
      if (r->has_edit_result()) return r->edit_result();
    }
  }
};

TEST_F(Identity, ATokenLetsAPlayerInAndEveryBadOneIsRefused) {
  test::ServerProcess server(server_args());
  auto expect_refused = [&](const std::string& t, wire::Error::Code code) {
    Client c;
    c.connect("127.0.0.1", server.port(), 5s);
    const wire::Envelope answer = hello(c, t);
    ASSERT_TRUE(answer.has_error()) << "token '" << t << "' was let in";
    EXPECT_EQ(answer.error().code(), code) << answer.error().message();
    EXPECT_FALSE(c.receive(5s).has_value()) << "the connection stayed open";
  };
  expect_refused("", wire::Error::AUTH_REQUIRED);
  expect_refused("not a token", wire::Error::BAD_TOKEN);
  expect_refused(std::string(600, 'A'), wire::Error::BAD_TOKEN);
  const auth::KeyPair other = auth::generate_key_pair();
  expect_refused(auth::mint_token({.player_id = "mallory",
                                   .display_name = "Mallory",
                                   .role = auth::Role::kAdmin,
                                   .expires_at = unix_now() + 600},
                                  other.seed),
                 wire::Error::BAD_TOKEN);
  std::string altered = token("alice");
  altered[30] = altered[30] == 'A' ? 'B' : 'A';
  expect_refused(altered, wire::Error::BAD_TOKEN);
  expect_refused(token("alice", auth::Role::kPlayer, -1), wire::Error::TOKEN_EXPIRED);

  Client c;
  c.connect("127.0.0.1", server.port(), 5s);
  const wire::Envelope welcome = hello(c, token("alice"));
  ASSERT_TRUE(welcome.has_welcome()) << welcome.DebugString();
  EXPECT_EQ(welcome.welcome().players(), 1u);
}

TEST_F(Identity, ASecondConnectionOfAPlayerReplacesTheFirst) {
  test::ServerProcess server(server_args());
  Client first, second, other;
  for (Client* c : {&first, &second, &other}) c->connect("127.0.0.1", server.port(), 5s);
  ASSERT_TRUE(hello(first, token("alice")).has_welcome());
  ASSERT_TRUE(hello(other, token("bob")).has_welcome());
  ASSERT_TRUE(hello(second, token("alice")).has_welcome());
  std::optional<wire::Envelope> m;
  while ((m = first.receive(10s)) && !m->has_error()) {
  }
  ASSERT_TRUE(m.has_value()) << "the first connection was not told";
  EXPECT_EQ(m->error().code(), wire::Error::REPLACED);
  EXPECT_FALSE(first.receive(5s).has_value()) << "the replaced connection stayed open";
  // The new connection and the other player go on.
  for (Client* c : {&second, &other}) {
    wire::Envelope ping;
    ping.mutable_ping()->set_nonce(5);
    c->send(ping);
    std::optional<wire::Envelope> pong;
    while ((pong = c->receive(10s)) && !pong->has_pong()) {
    }
    EXPECT_TRUE(pong.has_value());
  }
}

TEST_F(Identity, AViewerMayNotEditAndEditsAreLoggedUnderTheirAuthor) {
  const float y = static_cast<float>(world::TerrainGenerator(1).height_at(0, 0));
  {
    test::ServerProcess server(server_args());
    Client viewer, player;
    for (Client* c : {&viewer, &player}) c->connect("127.0.0.1", server.port(), 5s);
    ASSERT_TRUE(hello(viewer, token("vera", auth::Role::kViewer)).has_welcome());
    ASSERT_TRUE(hello(player, token("alice")).has_welcome());
    EXPECT_EQ(explode(viewer, 1, y).status(), wire::EditResult::FORBIDDEN);
    EXPECT_EQ(explode(player, 2, y).status(), wire::EditResult::ACCEPTED);
    EXPECT_EQ(server.terminate(), 0);
  }
  auto store = store::open_world_store((dir_ / "world").string(), {.read_only = true});
  std::vector<std::string> authors;
  store->for_each_edit(0, [&](const store::LoggedEdit& e) {
    authors.push_back(e.author);
    return true;
  });
  EXPECT_EQ(authors, std::vector<std::string>{"alice"});
}

TEST_F(Identity, OnlyAnAdminManagesRegionsAndTheyClipOtherPlayersEditsAcrossARestart) {
  const float y = static_cast<float>(world::TerrainGenerator(1).height_at(0, 0));
  const int iy = static_cast<int>(y);
  uint64_t id = 0;
  {
    test::ServerProcess server(server_args());
    auto admin = join(server.port(), token("root", auth::Role::kAdmin));
    auto alice = join(server.port(), token("alice"));
    auto mallory = join(server.port(), token("mallory"));
    auto vera = join(server.port(), token("vera", auth::Role::kViewer));
    EXPECT_EQ(ask(*mallory, list_regions()).region_result().status(),
              wire::RegionResult::FORBIDDEN);
    wire::Envelope add;
    add.mutable_region_command()->set_request_id(8);
    auto* r = add.mutable_region_command()->mutable_add();
    r->set_name("spawn");
    auto* b = r->mutable_box();
    b->set_min_x(-8), b->set_min_y(iy - 8), b->set_min_z(-8);
    b->set_max_x(8), b->set_max_y(iy + 4), b->set_max_z(8);
    r->set_protect_build(true), r->set_protect_explode(true);
    r->add_owners("alice");
    EXPECT_EQ(ask(*vera, add).region_result().status(), wire::RegionResult::FORBIDDEN);
    const wire::Envelope added = ask(*admin, add);
    ASSERT_EQ(added.region_result().status(), wire::RegionResult::OK)
        << added.region_result().reason();
    ASSERT_EQ(added.region_result().regions_size(), 1);
    id = added.region_result().regions(0).id();
    EXPECT_EQ(added.region_result().regions(0).created_by(), "root");

    const wire::Envelope clipped = ask(*mallory, explosion_at(-12, y, 0, 8, 1));
    EXPECT_EQ(clipped.edit_result().status(), wire::EditResult::ACCEPTED);
    ASSERT_EQ(clipped.edit_result().clipped_by_size(), 1);
    EXPECT_EQ(clipped.edit_result().clipped_by(0), id);
    wire::Envelope stamp;
    stamp.mutable_edit()->set_request_id(2);
    auto* s = stamp.mutable_edit()->mutable_stamp();
    s->set_shape(wire::Stamp::BOX);
    s->mutable_min()->set_x(-4), s->mutable_min()->set_y(y - 4), s->mutable_min()->set_z(-4);
    s->mutable_max()->set_x(4), s->mutable_max()->set_y(y), s->mutable_max()->set_z(4);
    s->set_solid(false);
    EXPECT_EQ(ask(*mallory, stamp).edit_result().status(), wire::EditResult::FORBIDDEN);
    const wire::Envelope owned = ask(*alice, stamp);
    EXPECT_EQ(owned.edit_result().status(), wire::EditResult::ACCEPTED);
    EXPECT_EQ(owned.edit_result().clipped_by_size(), 0);
    EXPECT_EQ(server.terminate(), 0);
  }
  test::ServerProcess server(server_args());
  auto mallory = join(server.port(), token("mallory"));
  EXPECT_EQ(ask(*mallory, explosion_at(12, y, 0, 8, 3)).edit_result().clipped_by_size(), 1)
      << "the region did not survive the restart";
  const std::string admin = token("root", auth::Role::kAdmin);
  std::string out;
  EXPECT_EQ(cli({"explode", "--at", "-12," + std::to_string(iy) + ",0", "--radius", "8"},
                server.port(), token("mallory"), &out),
            0);
  EXPECT_NE(out.find("clipped: protected region " + std::to_string(id)), std::string::npos) << out;
  EXPECT_EQ(cli({"region", "list"}, server.port(), token("mallory"), &out), 1);
  EXPECT_NE(out.find("FORBIDDEN"), std::string::npos) << out;
  EXPECT_EQ(cli({"region", "list"}, server.port(), admin, &out), 0) << out;
  EXPECT_NE(out.find("'spawn'"), std::string::npos) << out;
  EXPECT_NE(out.find("owners: alice"), std::string::npos) << out;
  EXPECT_EQ(cli({"region", "remove", std::to_string(id)}, server.port(), admin, &out), 0) << out;
  EXPECT_EQ(cli({"region", "remove", std::to_string(id)}, server.port(), admin, &out), 1);
  EXPECT_NE(out.find("NOT_FOUND"), std::string::npos) << out;
  EXPECT_EQ(cli({"region", "add", "--min", "0,0,0", "--max", "4,4,4", "--owner", "alice",
                 "--protect", "build"},
                server.port(), admin, &out),
            0)
      << out;
  EXPECT_EQ(cli({"region", "list"}, server.port(), admin, &out), 0);
  EXPECT_NE(out.find("1 protected region"), std::string::npos) << out;
  EXPECT_EQ(ask(*mallory, explosion_at(12, y, 0, 8, 4)).edit_result().clipped_by_size(), 0)
      << "removed, and the new region protects against building only";
}

TEST_F(Identity, APlayersEditBudgetIsSharedByItsConnectionsAndATokenMayOverrideIt) {
  auto args = server_args();
  for (const char* a : {"--edit-budget", "1000", "--edit-burst", "350000"}) args.push_back(a);
  test::ServerProcess server(args);
  const float y = static_cast<float>(world::TerrainGenerator(1).height_at(0, 0));
  {
    auto alice = join(server.port(), token("alice"));
    // A radius-28 explosion touches 57^3 = 185,193 samples: one fits the burst, two do not.
    EXPECT_EQ(ask(*alice, explosion_at(0, y, 0, 28, 1)).edit_result().status(),
              wire::EditResult::ACCEPTED);
  }
  auto again = join(server.port(), token("alice"));
  const wire::Envelope refused = ask(*again, explosion_at(0, y, 0, 28, 2));
  EXPECT_EQ(refused.edit_result().status(), wire::EditResult::RATE_LIMITED)
      << "reconnecting brought a fresh budget";
  EXPECT_GT(refused.edit_result().retry_after_ms(), 0u);
  auto bob = join(server.port(), token("bob"));
  EXPECT_EQ(ask(*bob, explosion_at(0, y, 0, 28, 3)).edit_result().status(),
            wire::EditResult::ACCEPTED)
      << "another player's budget was spent";
  Client rich;
  rich.connect("127.0.0.1", server.port(), 5s);
  const wire::Envelope welcome =
      hello(rich, token("carol", auth::Role::kPlayer, 600, 2000000, 4000000));
  ASSERT_TRUE(welcome.has_welcome());
  EXPECT_EQ(welcome.welcome().edit_budget_per_second(), 2000000);
  EXPECT_EQ(welcome.welcome().edit_budget_burst(), 4000000);
  for (uint64_t r = 10; r < 13; ++r)
    EXPECT_EQ(ask(rich, explosion_at(0, y, 0, 28, r)).edit_result().status(),
              wire::EditResult::ACCEPTED);
}

}  // namespace
}  // namespace vox
