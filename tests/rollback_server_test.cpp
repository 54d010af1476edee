// Rollbacks on a real voxeld (docs/PROTOCOL.md 4.12): players A and B explode the same
// chunks in turn; an admin rolls B back over the protocol; the world voxeld leaves on disk
// is byte for byte the world of A's edits alone. Across a restart the rollback is undone
// and B's edits are back. A player may not roll back; a rollback naming nothing is refused;
// voxel-cli rollback drives the same message.
#include <gtest/gtest.h>

#include <map>

#include "server/store/world_store.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/replay_util.hpp"
#include "tests/server_process.hpp"
#include "tests/token_world.hpp"

namespace vox {
namespace {

using namespace std::chrono_literals;
using client::Client;

constexpr uint64_t kSeed = 3;

struct Turn {
  char who;
  world::Explosion edit;
};

class Rollbacks : public test::TokenWorld {
 protected:
  Rollbacks() : TokenWorld("rollback_server") {}
  std::vector<std::string> server_args() const {
    auto args = key_and_world();
    args.insert(args.end(), {"--seed", std::to_string(kSeed)});
    return args;
  }
  static wire::EditResult explode(Client& c, const world::Explosion& x, uint64_t request) {
    wire::Envelope m;
    m.mutable_edit()->set_request_id(request);
    auto* e = m.mutable_edit()->mutable_explosion();
    e->mutable_center()->set_x(x.center.x), e->mutable_center()->set_y(x.center.y);
    e->mutable_center()->set_z(x.center.z);
    e->set_radius(x.radius), e->set_power(x.power);
    c.send(m);
    for (;;) {
      auto r = c.receive(20s);
      if (!r) return {};
      if (r->has_edit_result()) return r->edit_result();
    }
  }
  static wire::AdminResult ask(Client& c, wire::Envelope m) {
    m.mutable_admin_command()->set_request_id(9);
    c.send(m);
    for (;;) {
      auto r = c.receive(60s);
      if (!r) {
        ADD_FAILURE() << "no AdminResult: the connection closed or 60 s passed";
        return {};
      }
      if (r->has_error()) ADD_FAILURE() << "Error " << r->error().message();
      if (r->has_admin_result()) return r->admin_result();
    }
  }
  // The world on disk (voxeld stopped) against the edits not by `skip`, replayed onto the
  // seed: every chunk an edit reached.
  void expect_disk_world(const std::vector<Turn>& turns, char skip) {
    auto s = store::open_world_store((dir_ / "world").string(), {.read_only = true});
    std::map<world::ChunkCoord, uint64_t> stored;
    s->for_each_chunk([&](world::ChunkCoord c, uint64_t seq) { stored[c] = seq; });
    const world::TerrainGenerator gen(kSeed);
    const auto want = test::replayed_without(turns, skip, gen);
    for (const auto& [c, chunk] : want) {
      const world::Chunk disk =
          stored.count(c) ? store::read_checkpointed_chunk(*s, c) : gen.generate(c);
      EXPECT_TRUE(disk == chunk) << "chunk " << c.x << "," << c.y << "," << c.z;
    }
    EXPECT_GT(want.size(), 0u);
  }
};

TEST_F(Rollbacks, AnAdminRollsBBackOverTheProtocolLeavingAsWorldAndUndoesItAfterARestart) {
  const float y = static_cast<float>(world::TerrainGenerator(kSeed).height_at(16, 16));
  const std::vector<Turn> turns = {{'A', {{20, y, 16}, 6, 1}},    {'B', {{30, y, 16}, 7, 1.5f}},
                                   {'A', {{28, y, 18}, 4, 1}},    {'B', {{36, y, 20}, 5, 1}},
                                   {'A', {{33, y, 14}, 5, 0.5f}}, {'B', {{10, y, 40}, 6, 1}}};
  const std::string root = token("root", auth::Role::kAdmin);
  const std::string ops = token("ops", auth::Role::kAdmin);  // voxel-cli's (root stays joined)
  uint64_t record = 0;
  {
    test::ServerProcess server(server_args());
    auto alice = join(server.port(), token("alice"));
    auto bob = join(server.port(), token("bob"));
    auto admin = join(server.port(), root);
    uint64_t request = 1;
    for (const Turn& t : turns) {
      const wire::EditResult r = explode(t.who == 'A' ? *alice : *bob, t.edit, request++);
      ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.status();
    }
    wire::Envelope rollback;
    rollback.mutable_admin_command()->mutable_rollback()->set_player_id("bob");
    EXPECT_EQ(ask(*alice, rollback).status(), wire::AdminResult::FORBIDDEN);
    wire::Envelope everything;
    everything.mutable_admin_command()->mutable_rollback();
    const wire::AdminResult broad = ask(*admin, everything);
    EXPECT_EQ(broad.status(), wire::AdminResult::BAD_VALUE);
    EXPECT_NE(broad.reason().find("name a player, a box or a time"), std::string::npos);

    std::string out;
    EXPECT_EQ(cli({"rollback", "--player", "bob", "--dry-run"}, server.port(), ops, &out), 0)
        << out;
    EXPECT_NE(out.find("dry run: would undo 3 edit(s)"), std::string::npos) << out;
    const wire::AdminResult done = ask(*admin, rollback);
    ASSERT_EQ(done.status(), wire::AdminResult::OK) << done.reason();
    EXPECT_EQ(done.rollback().edits(), 3u);
    EXPECT_GT(done.rollback().chunks(), 0u);
    EXPECT_EQ(done.rollback().record(), turns.size() + 1);
    EXPECT_EQ(done.rollback().history_from(), 1u);
    record = done.rollback().record();
    EXPECT_EQ(server.terminate(), 0);
  }
  expect_disk_world(turns, 'B');
  {
    test::ServerProcess server(server_args());
    std::string out;
    EXPECT_EQ(cli({"rollback", "--undo", std::to_string(record)}, server.port(), root, &out), 0)
        << out;
    EXPECT_NE(out.find("brought back 3 edit(s)"), std::string::npos) << out;
    EXPECT_EQ(cli({"rollback", "--undo", std::to_string(record)}, server.port(), root, &out), 1);
    EXPECT_NE(out.find("is undone already"), std::string::npos) << out;
    EXPECT_EQ(server.terminate(), 0);
  }
  expect_disk_world(turns, 0);
}

}  // namespace
}  // namespace vox
