// Identity against a real voxeld started with --auth-public-key: a token the backend
// signed lets a player in under its name and role; a missing, malformed, foreign,
// altered or expired one is refused with its own Error and the connection closes; a
// second connection of a player replaces the first; a viewer may not edit; edits are
// logged under their author's player id.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "client/voxel_client.hpp"
#include "server/auth/player_token.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/server_process.hpp"

namespace vox {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using client::Client;

int64_t unix_now() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

class Identity : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("voxel_identity_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    key_ = auth::generate_key_pair();
    std::ofstream(dir_ / "game.pub") << auth::key_to_text(key_.public_key);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::vector<std::string> server_args() const {
    return {"--auth-public-key", (dir_ / "game.pub").string(), "--keep-log", "--world",
            (dir_ / "world").string()};
  }
  std::string token(const std::string& id, auth::Role role = auth::Role::kPlayer,
                    int64_t ttl = 600) const {
    return auth::mint_token({.player_id = id,
                             .display_name = "Name of " + id,
                             .role = role,
                             .expires_at = unix_now() + ttl},
                            key_.seed);
  }
  // Sends Hello with `token`; returns the first Welcome or Error the server answers.
  static wire::Envelope hello(Client& c, const std::string& token) {
    c.send(client::make_hello("ignored", 1, token));
    for (;;) {
      auto m = c.receive(10s);
      if (!m) return {};
      if (m->has_welcome() || m->has_error()) return *m;
    }
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

  fs::path dir_;
  auth::KeyPair key_;
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

}  // namespace
}  // namespace vox
