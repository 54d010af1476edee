// A real voxeld's players with tokens, for the identity, ban and reload tests: the game's
// key pair (its public key in a file voxeld reads), tokens it signs, a Hello and its
// answer, a joined client, and voxel-cli run in-process against the server.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "client-cli/commands.hpp"
#include "client/voxel_client.hpp"
#include "server/auth/player_token.hpp"
#include "tests/temp_dir.hpp"

namespace vox::test {

class TokenWorld : public ::testing::Test {
 protected:
  using Client = client::Client;
  explicit TokenWorld(const char* tag) : dir_(tag) {}
  void SetUp() override {
    key_ = auth::generate_key_pair();
    std::ofstream(dir_ / "game.pub") << auth::key_to_text(key_.public_key);
  }
  static int64_t unix_now() {
    return std::chrono::duration_cast<std::chrono::seconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  }
  // --auth-public-key and --world in the test's directory.
  std::vector<std::string> key_and_world() const {
    return {"--auth-public-key", (dir_ / "game.pub").string(), "--world",
            (dir_ / "world").string()};
  }
  std::string token(const std::string& id, auth::Role role = auth::Role::kPlayer, int64_t ttl = 600,
                    uint32_t edit_rate = 0, uint32_t edit_burst = 0) const {
    return auth::mint_token({.player_id = id,
                             .display_name = "Name of " + id,
                             .role = role,
                             .expires_at = unix_now() + ttl,
                             .edit_rate = edit_rate,
                             .edit_burst = edit_burst},
                            key_.seed);
  }
  // Sends Hello with `token`; returns the first Welcome or Error the server answers.
  static wire::Envelope hello(Client& c, const std::string& token) {
    c.send(client::make_hello("ignored", 1, token));
    for (;;) {
      auto m = c.receive(std::chrono::seconds(10));
      if (!m) return {};
      if (m->has_welcome() || m->has_error()) return *m;
    }
  }
  // A connected client that joined with `token`.
  std::unique_ptr<Client> join(uint16_t port, const std::string& token) {
    auto c = std::make_unique<Client>();
    c->connect("127.0.0.1", port, std::chrono::seconds(5));
    EXPECT_TRUE(hello(*c, token).has_welcome());
    return c;
  }
  // voxel-cli ARGS --server the port --token `token`; its exit code, its output in `out`.
  int cli(std::vector<std::string> args, uint16_t port, const std::string& token,
          std::string* out = nullptr) {
    args.push_back("--server=127.0.0.1:" + std::to_string(port));
    args.push_back("--token=" + token);
    std::ostringstream o, e;
    const int rc = cli::run_cli(args, o, e);
    if (out) *out = o.str() + e.str();
    return rc;
  }

  TempDir dir_;  // the key file and the world
  auth::KeyPair key_;
};

}  // namespace vox::test
