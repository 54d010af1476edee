// The durable world as an operator meets it: a real voxeld on a world directory, edits
// from a client, then kill -9 (or SIGTERM) and a restart on the same directory. Every edit
// whose EditResult said ACCEPTED is there, and the world is byte-identical to a fresh
// in-memory one that applied the same edits in the same order.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

#include "tests/session_test_util.hpp"

namespace vox::test {
namespace {

namespace fs = std::filesystem;

fs::path temp_world(const std::string& tag) {
  const fs::path dir =
      fs::temp_directory_path() / ("voxel_durable_" + std::to_string(::getpid()) + "_" + tag);
  fs::remove_all(dir);
  return dir;
}

wire::Envelope edit_message(uint64_t request, int kind, float x, float y, float z) {
  wire::Envelope m;
  auto* e = m.mutable_edit();
  e->set_request_id(request);
  auto set = [&](wire::Vec3* v, float dx, float dy, float dz) {
    v->set_x(x + dx);
    v->set_y(y + dy);
    v->set_z(z + dz);
  };
  switch (kind % 5) {
    case 0: {
      auto* b = e->mutable_brush();
      set(b->mutable_center(), 0, 0, 0);
      b->set_radius(5.5f);
      b->set_strength(0.7f);
      b->set_material(4);
      break;
    }
    case 1: {
      auto* x1 = e->mutable_explosion();
      set(x1->mutable_center(), 0.25f, 0, 0);
      x1->set_radius(7);
      x1->set_power(1.3f);
      break;
    }
    case 2: {
      auto* s = e->mutable_smooth();
      set(s->mutable_center(), 0, -1, 0);
      s->set_radius(6);
      s->set_strength(0.5f);
      break;
    }
    case 3: {
      auto* p = e->mutable_paint();
      set(p->mutable_center(), 0, 0, 0);
      p->set_radius(6);
      p->set_material(3);
      break;
    }
    default: {
      auto* s = e->mutable_stamp();
      s->set_shape(wire::Stamp::BOX);
      set(s->mutable_min(), -4, 2, -4);
      set(s->mutable_max(), 3.5f, 9, 4);
      s->set_material(2);
      break;
    }
  }
  return m;
}

// Edits across a chunk border, of every kind, some on top of each other.
std::vector<wire::Envelope> some_edits() {
  std::vector<wire::Envelope> out;
  for (int i = 0; i < 10; ++i) {
    const float x = 28.0f + 3.0f * static_cast<float>(i % 4), z = 30.0f - 2.0f * (i % 3);
    out.push_back(edit_message(static_cast<uint64_t>(i + 1), i, x, surface_y(x, z), z));
  }
  return out;
}

void apply_all(const ServerProcess& server, const std::vector<wire::Envelope>& edits) {
  auto c = player(server, "editor");
  for (const auto& e : edits) {
    const auto r = edit_and_wait(*c, e);
    ASSERT_TRUE(r) << "no EditResult";
    ASSERT_EQ(r->edit_result().status(), wire::EditResult::ACCEPTED) << r->edit_result().reason();
  }
}

// Every chunk's encoding of a radius-2 view around the edits, as a fresh client gets it.
std::map<client::ChunkKey, std::vector<uint8_t>> world_seen(const ServerProcess& server) {
  auto c = player(server, "viewer");
  view(*c, 32, surface_y(32, 28), 28, 2);
  std::map<client::ChunkKey, std::vector<uint8_t>> out;
  for (const auto& [key, held] : c->chunks()) out[key] = held.encoding;
  return out;
}

std::map<client::ChunkKey, std::vector<uint8_t>> fresh_world_after(
    const std::vector<wire::Envelope>& edits) {
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  return world_seen(fresh);
}

TEST(Durability, AcceptedEditsSurviveKillNineAndTheWorldIsByteIdentical) {
  const fs::path world = temp_world("kill9");
  const auto edits = some_edits();
  {
    ServerProcess s({"--world", world.string()});
    apply_all(s, edits);
  }  // SIGKILL right after the last ACCEPTED
  std::map<client::ChunkKey, std::vector<uint8_t>> restarted;
  {
    ServerProcess s({"--world", world.string()});
    restarted = world_seen(s);
  }
  const auto expected = fresh_world_after(edits);
  ASSERT_FALSE(expected.empty());
  EXPECT_TRUE(restarted == expected) << "the restarted world differs from the edits replayed";
  // And the untouched world differs from both: the edits were really there.
  ServerProcess untouched({"--in-memory"});
  EXPECT_FALSE(world_seen(untouched) == expected);
  fs::remove_all(world);
}

TEST(Durability, ACleanStopKeepsEveryEditAndExitsZero) {
  const fs::path world = temp_world("sigterm");
  const auto edits = some_edits();
  {
    ServerProcess s({"--world", world.string()});
    apply_all(s, edits);
    EXPECT_EQ(s.terminate(), 0);
  }
  ServerProcess s({"--world", world.string()});
  EXPECT_TRUE(world_seen(s) == fresh_world_after(edits));
  fs::remove_all(world);
}

TEST(Durability, AWorldStartedWithAnotherSeedIsRefusedNamingBoth) {
  const fs::path world = temp_world("seed");
  { ServerProcess s({"--world", world.string(), "--seed", "7"}); }
  const fs::path out = world.string() + ".out";
  const std::string cmd = std::string(VOXELD_PATH) + " --port 0 --world " + world.string() +
                          " --seed 8 > " + out.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << status;
  std::ifstream in(out);
  const std::string text{std::istreambuf_iterator<char>(in), {}};
  EXPECT_NE(text.find("seed 7"), std::string::npos) << text;
  EXPECT_NE(text.find("not 8"), std::string::npos) << text;
  // Without --seed, the world's own seed is used.
  ServerProcess s({"--world", world.string()});
  auto c = connect_to(s);
  EXPECT_EQ(c->handshake("p", 5s * kSlow).world_seed(), 7u);
  fs::remove_all(world);
  fs::remove(out);
}

}  // namespace
}  // namespace vox::test
