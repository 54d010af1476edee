// A real voxeld on 127.0.0.1: the view-complete marker (ViewReady) and the recovery of a
// client whose copy of a chunk went bad (Resync), as PROTOCOL.md 4.2 and 4.3 describe.
#include <gtest/gtest.h>

#include <set>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "tests/session_test_util.hpp"

namespace vox::net {
namespace {

using namespace std::chrono_literals;
using client::ChunkKey;
using client::make_brush;
using test::player;
using test::surface_y;
using test::wait_for;

int64_t d2(const wire::ChunkCoord& a, const wire::ChunkCoord& b) {
  const int64_t x = a.x() - b.x(), y = a.y() - b.y(), z = a.z() - b.z();
  return x * x + y * y + z * z;
}

size_t chunks_in_sphere(int r) {
  size_t n = 0;
  for (int z = -r; z <= r; ++z)
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x) n += x * x + y * y + z * z <= r * r;
  return n;
}

TEST(ViewSync, ViewReadyComesAfterEveryChunkOfTheViewWithItsCounts) {
  test::ServerProcess server;
  auto c = player(server, "viewer");
  const float y = surface_y(16, 16);
  const auto messages = test::view_messages(*c, 16, y, 16, 3, 7);
  ASSERT_FALSE(messages.empty());
  ASSERT_TRUE(messages.back().has_view_ready());
  const wire::ViewReady& ready = messages.back().view_ready();
  EXPECT_EQ(ready.view_id(), 7u);
  EXPECT_EQ(ready.radius(), 3u);
  std::set<ChunkKey> sent;
  for (const auto& m : messages) {
    if (!m.has_chunk_mesh()) continue;
    sent.insert(client::key_of(m.chunk_mesh().coord()));
    EXPECT_LE(d2(m.chunk_mesh().coord(), ready.center()), 9) << "a chunk outside the view";
  }
  EXPECT_EQ(ready.chunks_sent(), sent.size());
  EXPECT_EQ(sent.size(), c->chunks().size());
  EXPECT_EQ(ready.chunks_sent() + ready.chunks_empty(), chunks_in_sphere(3));
  EXPECT_GT(ready.chunks_empty(), 0u) << "a radius-3 view at the surface has air and rock chunks";
  // Nothing of the view is missing: a second client gets the same set, and moving the
  // view gives a ViewReady for the new one.
  auto other = player(server, "other");
  const wire::ViewReady again = test::view(*other, 16, y, 16, 3, 1);
  EXPECT_EQ(again.chunks_sent(), ready.chunks_sent());
  const wire::ViewReady moved = test::view(*c, 16 + 64, y, 16, 3, 8);
  EXPECT_EQ(moved.view_id(), 8u);
  EXPECT_EQ(moved.center().x(), ready.center().x() + 2);
}

TEST(ViewSync, AViewReplacedBeforeItIsCompleteGetsNoViewReady) {
  test::ServerProcess server({"--set-view-rate", "0"});  // every SetView applied at once
  auto c = player(server, "mover");
  const float y = surface_y(500, 500);
  c->send(client::make_set_view(500, y, 500, 4, 1));  // far from loaded terrain
  auto messages = test::view_messages(*c, 2000, surface_y(2000, 2000), 2000, 2, 2);
  while (auto more = c->receive(500ms * test::kSlow)) messages.push_back(std::move(*more));
  size_t ready = 0;
  for (const auto& m : messages) ready += m.has_view_ready() ? 1 : 0;
  EXPECT_EQ(ready, 1u) << "one ViewReady, for view 2: view 1 was replaced before it was complete";
}

// The documented recovery (PROTOCOL.md 4.3): a client whose base went bad cannot apply
// the next delta (the CRC-32C says so), asks for the chunk again and gets it in full; the
// deltas after it apply to that copy.
TEST(ViewSync, ResyncSendsAFullCopyAfterTheClientsBaseWentBad) {
  test::ServerProcess server;
  auto a = player(server, "corrupted");
  auto editor = player(server, "editor");
  const float y = surface_y(16, 16);
  test::view(*a, 16, y, 16, 2);
  test::view(*editor, 16, y, 16, 2);
  auto result = test::edit_and_wait(*editor, make_brush(1, 16.5f, y, 16.5f, 3, 1, false));
  ASSERT_TRUE(result);
  ASSERT_EQ(result->edit_result().status(), wire::EditResult::ACCEPTED);
  ASSERT_GT(result->edit_result().changed_chunks_size(), 0);
  // A's delta of a changed chunk, applied to a corrupted copy of its base, fails.
  auto delta = wait_for(
      *a, [](const wire::Envelope& m) { return m.has_chunk_mesh(); }, 10s);
  ASSERT_TRUE(delta);
  const wire::ChunkMesh& d = delta->chunk_mesh();
  ASSERT_NE(d.base_version(), 0u);
  const ChunkKey key = client::key_of(d.coord());
  ASSERT_TRUE(a->chunks().count(key));
  std::vector<uint8_t> bad_base = a->chunks().at(key).encoding;
  bad_base[bad_base.size() / 2] ^= 0x5a;
  proto::ZstdCodec zstd;
  mesh::Buffer<uint8_t> expanded;
  const auto* p = reinterpret_cast<const uint8_t*>(d.payload().data());
  const bool applies =
      !zstd.decompress_into({p, d.payload().size()}, bad_base, 1 << 22, expanded) &&
      proto::decode_mesh({expanded.data(), expanded.size()});
  EXPECT_FALSE(applies) << "a delta applied to a corrupted base must not decode";
  // Recovery: Resync, then a full copy equal to what a fresh client gets.
  const wire::ChunkCoord coord = d.coord();
  a->send(client::make_resync({&coord, 1}));
  auto full = wait_for(*a, [&](const wire::Envelope& m) {
    return m.has_chunk_mesh() && client::key_of(m.chunk_mesh().coord()) == key;
  });
  ASSERT_TRUE(full) << "no copy of the resynced chunk";
  EXPECT_EQ(full->chunk_mesh().base_version(), 0u) << "a resync is answered in full";
  auto fresh = player(server, "fresh");
  test::view(*fresh, 16, y, 16, 2);
  ASSERT_TRUE(fresh->chunks().count(key));
  EXPECT_EQ(a->chunks().at(key).version, fresh->chunks().at(key).version);
  EXPECT_EQ(a->chunks().at(key).encoding, fresh->chunks().at(key).encoding);
  // The next change is a delta against the resynced copy, and it applies.
  ASSERT_TRUE(test::edit_and_wait(*editor, make_brush(2, 16.5f, y, 16.5f, 3, 1, true)));
  auto next = wait_for(*a, [&](const wire::Envelope& m) {
    return m.has_chunk_mesh() && client::key_of(m.chunk_mesh().coord()) == key;
  });
  ASSERT_TRUE(next);
  EXPECT_NE(next->chunk_mesh().base_version(), 0u);
}

TEST(ViewSync, ResyncOverTheLimitIsRefusedAndOutsideTheViewIgnored) {
  test::ServerProcess server;
  auto c = player(server, "asker");
  const wire::Welcome w = [&] {
    client::Client probe;
    probe.connect("127.0.0.1", server.port(), 5s);
    return probe.handshake("probe", 5s * test::kSlow);
  }();
  ASSERT_GT(w.max_resync_chunks(), 0u);
  const float y = surface_y(16, 16);
  test::view(*c, 16, y, 16, 1);
  std::vector<wire::ChunkCoord> many(w.max_resync_chunks() + 1);
  c->send(client::make_resync(many));
  auto error = wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); });
  ASSERT_TRUE(error);
  EXPECT_EQ(error->error().code(), wire::Error::BAD_VALUE);
  // A chunk with a published mesh (another player's view), outside this client's view.
  auto other = player(server, "elsewhere");
  const wire::ViewReady there = test::view(*other, 3200, surface_y(3200, 16), 16, 0);
  ASSERT_EQ(there.chunks_sent() + there.chunks_empty(), 1u)
      << "the other view's one chunk is published";
  c->send(client::make_resync({&there.center(), 1}));
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(9);
  c->send(ping);
  auto pong = wait_for(*c, [](const wire::Envelope& m) {
    return m.has_pong() || m.has_chunk_mesh() || m.has_error();
  });
  ASSERT_TRUE(pong);
  EXPECT_TRUE(pong->has_pong()) << "a chunk outside the view is not sent, and is not an error";
  EXPECT_FALSE(c->receive(300ms * test::kSlow)) << "nothing else comes";
}

}  // namespace
}  // namespace vox::net
