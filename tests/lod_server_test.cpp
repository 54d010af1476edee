// A real voxeld on 127.0.0.1 streaming a level-of-detail view (PROTOCOL.md
// 4.10): what the client holds is its layout, the chunks of all levels meet without
// cracks, edits reach the coarse levels, moving unloads, and bad requests are refused.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "proto/mesh_codec.hpp"
#include "server/world/lod_layout.hpp"
#include "tests/mesh_test_util.hpp"
#include "tests/session_test_util.hpp"

namespace vox::net {
namespace {

using namespace std::chrono_literals;
using test::player;
using test::surface_y;
using test::wait_for;
using world::LodChunk;
using world::LodLayout;

struct Eye {
  float x, y, z;
  std::array<double, 3> voxels() const { return {x, y, z}; }
};

// SetView with levels 0 .. level, then receives until its ViewReady (applying meshes and
// unloads); the messages in order, the ViewReady last.
std::vector<wire::Envelope> lod_view(client::Client& c, Eye e, uint32_t radius, uint64_t id,
                                     uint32_t level, float distance = 1.0f) {
  return test::view_messages(c, e.x, e.y, e.z, radius, id, level, distance);
}

// The layout the server lays out for that SetView (view_feed.cpp's settings).
LodLayout layout_for(Eye e, uint32_t radius, uint32_t level, double distance) {
  LodLayout layout({.levels = static_cast<int>(level) + 1,
                    .top_radius = 1,
                    .split_distance = distance,
                    .near_split_distance = std::max(0.5, radius / 2.0)});
  layout.update(e.voxels());
  return layout;
}

// Every chunk the client holds, decoded, in world positions.
mesh::ChunkMesh held_world_mesh(const client::Client& c, uint32_t levels) {
  mesh::ChunkMesh all;
  for (uint32_t level = 0; level <= levels; ++level) {
    const auto& held = level == 0 ? c.chunks() : c.lod_chunks(level);
    const float scale = static_cast<float>(1u << level);
    for (const auto& [key, chunk] : held) {
      auto decoded = proto::decode_mesh(chunk.encoding);
      EXPECT_TRUE(decoded.ok());
      if (!decoded.ok()) continue;
      const auto [x, y, z] = key;
      const float side = 32.0f * scale;
      const auto base = static_cast<uint32_t>(all.positions.size());
      for (const mesh::Vec3f& p : decoded.value().positions)
        all.positions.push_back({static_cast<float>(x) * side + p.x * scale,
                                 static_cast<float>(y) * side + p.y * scale,
                                 static_cast<float>(z) * side + p.z * scale});
      for (uint32_t i : decoded.value().indices) all.indices.push_back(base + i);
    }
  }
  return all;
}

TEST(LodServer, TheClientHoldsItsLayoutAndTheLevelsMeetWithoutCracks) {
  test::ServerProcess server;
  auto c = player(server, "far-sighted");
  const Eye eye{40.5f, surface_y(40, -20) + 2.0f, -20.5f};
  const auto messages = lod_view(*c, eye, 2, 1, 3);
  ASSERT_FALSE(messages.empty());
  ASSERT_TRUE(messages.back().has_view_ready());
  const wire::ViewReady& ready = messages.back().view_ready();
  const LodLayout layout = layout_for(eye, 2, 3, 1.0);

  size_t level0 = 0, coarse = 0;
  std::map<uint32_t, size_t> per_level;
  for (const LodChunk& l : layout.chunks()) (l.level == 0 ? level0 : coarse) += 1;
  EXPECT_EQ(ready.chunks_sent() + ready.chunks_empty(), level0);
  EXPECT_EQ(ready.lod_chunks_sent() + ready.lod_chunks_empty(), coarse);
  EXPECT_EQ(ready.chunks_sent(), c->chunks().size());
  size_t lod_held = 0;
  for (uint32_t level = 1; level <= 3; ++level) {
    for (const auto& [key, chunk] : c->lod_chunks(level)) {
      const auto [x, y, z] = key;
      EXPECT_TRUE(layout.chunks().count({static_cast<int>(level), {x, y, z}}))
          << "level " << level << " chunk " << x << " " << y << " " << z << " is not in the layout";
      ++lod_held;
    }
    per_level[level] = c->lod_chunks(level).size();
  }
  for (const auto& [key, chunk] : c->chunks()) {
    const auto [x, y, z] = key;
    EXPECT_TRUE(layout.chunks().count({0, {x, y, z}})) << "level-0 chunk outside the layout";
  }
  EXPECT_EQ(ready.lod_chunks_sent(), lod_held);
  EXPECT_GT(per_level[1], 0u);
  EXPECT_GT(per_level[2], 0u);

  // As the client sees it: one surface, open only at the layout's outer faces.
  const test::Topology t = test::analyse(held_world_mesh(*c, 3));
  EXPECT_EQ(t.misoriented_edges, 0u);
  // Vertices rounded onto a sample can meet several others there, at level 0 as on any
  // level (lod_mesher_test.cpp); anywhere else an edge is in two triangles.
  for (const auto& ce : t.crowded_edges) {
    auto on_sample = [](const mesh::Vec3f& p) {
      return p.x == std::floor(p.x) && p.y == std::floor(p.y) && p.z == std::floor(p.z);
    };
    EXPECT_TRUE(on_sample(ce[0]) || on_sample(ce[1]))
        << "(" << ce[0].x << ", " << ce[0].y << ", " << ce[0].z << ") - (" << ce[1].x << ", "
        << ce[1].y << ", " << ce[1].z << ")";
  }
  const float top = 32.0f * 8.0f;
  const float e[3] = {eye.x, eye.y, eye.z};
  size_t inner = 0;
  for (const auto& edge : t.open_edges) {
    bool outer = false;
    for (int a = 0; a < 3; ++a) {
      const float lo = (std::floor(e[a] / top) - 1.0f) * top, hi = lo + 3.0f * top;
      const float u = (&edge[0].x)[a], v = (&edge[1].x)[a];
      outer |= (u == lo && v == lo) || (u == hi && v == hi);
    }
    inner += !outer;
  }
  EXPECT_EQ(inner, 0u) << "open edges inside the layout: a crack between chunks";
}

TEST(LodServer, AnEditReachesTheCoarseChunkOverItWithinASecond) {
  test::ServerProcess server;
  auto c = player(server, "digger");
  const Eye eye{16.5f, surface_y(16, 16) + 2.0f, 16.5f};
  lod_view(*c, eye, 2, 1, 2);
  // 150 voxels east: beyond level 0 (about 2 chunks), in a level-1 or level-2 chunk.
  const float x = 166.0f, z = 16.0f, y = surface_y(166, 16);
  const LodLayout layout = layout_for(eye, 2, 2, 1.0);
  std::optional<LodChunk> over;
  for (const LodChunk& l : layout.chunks()) {
    const auto lo = l.lo();
    if (l.level > 0 && x >= lo[0] && x < lo[0] + l.side() && y >= lo[1] && y < lo[1] + l.side() &&
        z >= lo[2] && z < lo[2] + l.side())
      over = l;
  }
  ASSERT_TRUE(over) << "the edit is not under a coarse chunk of the layout";
  const auto t0 = client::Clock::now();
  c->send(client::make_brush(9, x, y, z, 12.0f, 1.0f, true));
  const auto delta = wait_for(
      *c,
      [&](const wire::Envelope& m) {
        return m.has_chunk_mesh() && static_cast<int>(m.chunk_mesh().level()) == over->level &&
               m.chunk_mesh().coord().x() == over->c.x && m.chunk_mesh().coord().y() == over->c.y &&
               m.chunk_mesh().coord().z() == over->c.z;
      },
      5s);
  ASSERT_TRUE(delta) << "no new mesh of the level-" << over->level << " chunk over the edit";
  EXPECT_NE(delta->chunk_mesh().base_version(), 0u) << "a delta against the held version";
  EXPECT_LT(client::Clock::now() - t0, 1s * test::kSlow);
}

TEST(LodServer, MovingFarUnloadsTheCoarseChunksTheLayoutDropped) {
  test::ServerProcess server;
  auto c = player(server, "walker");
  const Eye a{16.5f, surface_y(16, 16) + 2.0f, 16.5f};
  lod_view(*c, a, 1, 1, 2);
  ASSERT_GT(c->lod_chunks(2).size(), 0u);
  const Eye b{2000.5f, surface_y(2000, 16) + 2.0f, 16.5f};
  const auto messages = lod_view(*c, b, 1, 2, 2);
  size_t unloaded_coarse = 0;
  for (const auto& m : messages)
    if (m.has_chunk_unload() && m.chunk_unload().level() > 0)
      unloaded_coarse += static_cast<size_t>(m.chunk_unload().coords_size());
  EXPECT_GT(unloaded_coarse, 0u);
  const LodLayout layout = layout_for(b, 1, 2, 1.0);
  for (uint32_t level = 1; level <= 2; ++level)
    for (const auto& [key, chunk] : c->lod_chunks(level)) {
      const auto [x, y, z] = key;
      EXPECT_TRUE(layout.chunks().count({static_cast<int>(level), {x, y, z}}))
          << "a chunk of the old layout was not unloaded";
    }
  // Back to a level-0 view: every coarse chunk goes.
  test::view(*c, b.x, b.y, b.z, 1, 3);
  for (uint32_t level = 1; level <= 2; ++level) EXPECT_TRUE(c->lod_chunks(level).empty());
}

TEST(LodServer, AResyncOfACoarseChunkSendsItInFull) {
  test::ServerProcess server;
  auto c = player(server, "resyncer");
  const Eye eye{16.5f, surface_y(16, 16) + 2.0f, 16.5f};
  lod_view(*c, eye, 1, 1, 2);
  ASSERT_FALSE(c->lod_chunks(1).empty());
  // Plain copies: a lambda may not capture structured bindings before C++20 in clang 15.
  const int x = std::get<0>(c->lod_chunks(1).begin()->first),
            y = std::get<1>(c->lod_chunks(1).begin()->first),
            z = std::get<2>(c->lod_chunks(1).begin()->first);
  wire::ChunkCoord coord;
  coord.set_x(x);
  coord.set_y(y);
  coord.set_z(z);
  c->send(client::make_resync(std::span(&coord, 1), 1));
  const auto full = wait_for(*c, [&](const wire::Envelope& m) {
    return m.has_chunk_mesh() && m.chunk_mesh().level() == 1 && m.chunk_mesh().coord().x() == x &&
           m.chunk_mesh().coord().y() == y && m.chunk_mesh().coord().z() == z;
  });
  ASSERT_TRUE(full);
  EXPECT_EQ(full->chunk_mesh().base_version(), 0u);
}

TEST(LodServer, ALevelOrDistanceOutOfBoundsIsRefusedAndTheConnectionStays) {
  test::ServerProcess server;
  auto c = player(server, "greedy");
  const auto bad = [&](uint32_t level, float distance) {
    c->send(client::make_set_view(0, 0, 0, 1, 1, level, distance));
    const auto m = wait_for(
        *c, [](const wire::Envelope& e) { return e.has_error(); }, 5s);
    ASSERT_TRUE(m);
    EXPECT_EQ(m->error().code(), wire::Error::BAD_VALUE) << m->error().message();
  };
  bad(7, 1.0f);
  bad(2, 0.5f);
  bad(2, 4.5f);
  bad(2, std::numeric_limits<float>::quiet_NaN());
  bad(2, std::numeric_limits<float>::infinity());
  const Eye eye{16.5f, surface_y(16, 16) + 2.0f, 16.5f};
  const auto ok = lod_view(*c, eye, 1, 9, 1);
  ASSERT_FALSE(ok.empty());
  EXPECT_TRUE(ok.back().has_view_ready());
}

}  // namespace
}  // namespace vox::net
