// Queries over the protocol (docs/PROTOCOL.md 4.13) against a real voxeld: raycast, ground
// and samples in order with the sender's edits, the yield an edit reports, and what a
// hostile or greedy client gets.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "client/voxel_client.hpp"
#include "tests/session_test_util.hpp"

namespace vox::net {
namespace {

using namespace std::chrono_literals;
using test::kSlow;
using test::player;
using test::wait_for;

wire::Envelope ground(uint64_t id, float x, float z, float from_y = 200, float depth = 400) {
  wire::Envelope m;
  auto* q = m.mutable_query();
  q->set_request_id(id);
  auto* g = q->mutable_ground();
  g->set_x(x), g->set_z(z), g->set_from_y(from_y), g->set_max_depth(depth);
  return m;
}

wire::Envelope ray(uint64_t id, std::array<float, 3> from, std::array<float, 3> dir, float max) {
  wire::Envelope m;
  auto* q = m.mutable_query();
  q->set_request_id(id);
  auto* r = q->mutable_raycast();
  r->mutable_origin()->set_x(from[0]), r->mutable_origin()->set_y(from[1]);
  r->mutable_origin()->set_z(from[2]);
  r->mutable_direction()->set_x(dir[0]), r->mutable_direction()->set_y(dir[1]);
  r->mutable_direction()->set_z(dir[2]);
  r->set_max_distance(max);
  return m;
}

wire::Envelope samples(uint64_t id, std::array<int32_t, 3> lo, std::array<int32_t, 3> hi) {
  wire::Envelope m;
  auto* q = m.mutable_query();
  q->set_request_id(id);
  auto* b = q->mutable_samples()->mutable_box();
  b->set_min_x(lo[0]), b->set_min_y(lo[1]), b->set_min_z(lo[2]);
  b->set_max_x(hi[0]), b->set_max_y(hi[1]), b->set_max_z(hi[2]);
  return m;
}

wire::QueryResult ask(client::Client& c, const wire::Envelope& query) {
  c.send(query);
  const uint64_t id = query.query().request_id();
  auto m = wait_for(c, [id](const wire::Envelope& e) {
    return e.has_query_result() && e.query_result().request_id() == id;
  });
  EXPECT_TRUE(m) << "no QueryResult " << id;
  return m ? m->query_result() : wire::QueryResult{};
}

wire::Envelope explosion(uint64_t id, float x, float y, float z, float radius, float power) {
  wire::Envelope m;
  auto* e = m.mutable_edit();
  e->set_request_id(id);
  auto* x_ = e->mutable_explosion();
  x_->mutable_center()->set_x(x), x_->mutable_center()->set_y(y), x_->mutable_center()->set_z(z);
  x_->set_radius(radius), x_->set_power(power);
  return m;
}

int16_t density_at(const wire::QueryResult& r, size_t i) {
  const std::string& d = r.densities();
  return static_cast<int16_t>(static_cast<uint8_t>(d[2 * i]) | static_cast<uint8_t>(d[2 * i + 1])
                                                                   << 8);
}

TEST(Queries, GroundRaycastAndSamplesAgreeOverTheProtocol) {
  test::ServerProcess server({"--in-memory"});
  auto c = player(server, "surveyor");
  const wire::QueryResult g = ask(*c, ground(1, 10.5f, 3.25f));
  ASSERT_EQ(g.status(), wire::QueryResult::OK) << g.reason();
  ASSERT_TRUE(g.hit());
  EXPECT_NEAR(g.point().x(), 10.5f, 1e-3);
  EXPECT_NEAR(g.point().z(), 3.25f, 1e-3);
  EXPECT_NEAR(g.point().y(), test::surface_y(10.5f, 3.25f), 3.0f);
  EXPECT_GT(g.normal().y(), 0.0f);
  EXPECT_NE(g.material(), 0u);
  EXPECT_NEAR(g.distance(), 200.0f - g.point().y(), 1e-3);

  // The same ray as a raycast, its direction of any length.
  const wire::QueryResult r = ask(*c, ray(2, {10.5f, 200, 3.25f}, {0, -7, 0}, 400));
  ASSERT_EQ(r.status(), wire::QueryResult::OK);
  EXPECT_TRUE(r.hit());
  EXPECT_FLOAT_EQ(r.point().y(), g.point().y());
  // Up into the sky: nothing.
  const wire::QueryResult up = ask(*c, ray(3, {10.5f, g.point().y() + 2, 3.25f}, {0, 1, 0}, 300));
  ASSERT_EQ(up.status(), wire::QueryResult::OK);
  EXPECT_FALSE(up.hit());

  // The column's samples: solid below the ground, air above it.
  const int32_t y0 = static_cast<int32_t>(std::floor(g.point().y()));
  const wire::QueryResult s = ask(*c, samples(4, {10, y0 - 3, 3}, {11, y0 + 4, 4}));
  ASSERT_EQ(s.status(), wire::QueryResult::OK) << s.reason();
  EXPECT_EQ(s.box().min_y(), y0 - 3);
  ASSERT_EQ(s.materials().size(), 2u * 8 * 2);
  ASSERT_EQ(s.densities().size(), 2 * s.materials().size());
  for (int x = 0; x < 2; ++x) {
    EXPECT_GT(density_at(s, x), 0) << "3 below the ground";  // y = y0 - 3, z = 3
    EXPECT_LT(density_at(s, 7 * 2 + x), 0) << "4 above it";  // y = y0 + 4
  }
}

TEST(Queries, AQuerySentAfterAnEditSeesItAndTheEditReportsItsYield) {
  test::ServerProcess server({"--in-memory"});
  auto c = player(server, "miner");
  const wire::QueryResult before = ask(*c, ground(1, 0.5f, 0.5f));
  ASSERT_TRUE(before.hit());
  const float y = before.point().y();
  // The explosion and the query go out together: the query sees the edit. Their answers
  // come in either order (PROTOCOL 4.7): in one batch the query's goes first, in two the
  // edit's.
  c->send(explosion(7, 0.5f, y, 0.5f, 6, 3));
  c->send(ground(2, 0.5f, 0.5f));
  std::optional<wire::QueryResult> after;
  std::optional<wire::EditResult> result;
  while (!after || !result) {
    auto m = wait_for(
        *c, [](const wire::Envelope& e) { return e.has_edit_result() || e.has_query_result(); });
    ASSERT_TRUE(m) << "no answer";
    if (m->has_query_result()) after = m->query_result();
    if (m->has_edit_result()) result = m->edit_result();
  }
  ASSERT_TRUE(after->hit());
  EXPECT_LT(after->point().y(), y - 2.0f);
  ASSERT_EQ(result->status(), wire::EditResult::ACCEPTED);
  double removed = 0, added = 0;
  for (const wire::MaterialVolume& v : result->volumes()) {
    EXPECT_GE(v.material(), 1u);
    removed += v.removed(), added += v.added();
  }
  EXPECT_GT(removed, 100.0);  // a radius-6 crater, half of it in the ground
  EXPECT_EQ(added, 0.0);
}

TEST(Queries, HostileQueriesAreRefusedBadValueAndTheConnectionGoesOn) {
  test::ServerProcess server({"--in-memory"});
  auto c = player(server, "mallory");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<wire::Envelope> bad = {
      ray(1, {nan, 0, 0}, {0, -1, 0}, 10),
      ray(2, {0, 0, 0}, {0, 0, 0}, 10),
      ray(3, {0, 0, 0}, {1e-30f, 0, 0}, 10),
      ray(4, {0, 0, 0}, {0, -1, 0}, 0),
      ray(5, {0, 0, 0}, {0, -1, 0}, 1e9f),
      ray(6, {0, 0, 0}, {inf, -1, 0}, 10),
      ray(7, {3e6f, 0, 0}, {0, -1, 0}, 10),
      ground(8, 0, 0, 100, -1),
      ground(9, 0, 0, 1e9f, 10),
      samples(10, {0, 0, 0}, {32, 32, 32}),  // 33^3 samples
      samples(11, {5, 0, 0}, {4, 0, 0}),
      samples(12, {INT32_MIN, 0, 0}, {INT32_MIN + 1, 0, 0}),
      samples(13, {0, 0, 0}, {INT32_MAX, INT32_MAX, INT32_MAX}),
  };
  wire::Envelope empty;
  empty.mutable_query()->set_request_id(14);
  bad.push_back(empty);
  for (const wire::Envelope& q : bad) {
    const wire::QueryResult r = ask(*c, q);
    EXPECT_EQ(r.status(), wire::QueryResult::BAD_VALUE) << q.query().request_id();
    EXPECT_FALSE(r.reason().empty());
    EXPECT_FALSE(r.hit());
    EXPECT_TRUE(r.densities().empty());
  }
  // Still served.
  const wire::QueryResult ok = ask(*c, ground(20, 0, 0));
  EXPECT_EQ(ok.status(), wire::QueryResult::OK);
}

TEST(Queries, AClientOverItsQueryRateIsToldWhenToAskAgain) {
  test::ServerProcess server({"--in-memory", "--query-rate", "2"});
  auto c = player(server, "greedy");
  // A burst of 4 passes; of 8 at once the rest are refused with a time to retry.
  for (uint64_t i = 1; i <= 8; ++i) c->send(ground(i, 0, 0));
  int ok = 0, limited = 0;
  for (int n = 0; n < 8; ++n) {
    auto m = wait_for(*c, [](const wire::Envelope& e) { return e.has_query_result(); });
    ASSERT_TRUE(m);
    const wire::QueryResult& r = m->query_result();
    if (r.status() == wire::QueryResult::OK) ++ok;
    if (r.status() == wire::QueryResult::RATE_LIMITED) {
      ++limited;
      EXPECT_GT(r.retry_after_ms(), 0u);
      EXPECT_LE(r.retry_after_ms(), 1000u);
    }
  }
  EXPECT_EQ(ok, 4);
  EXPECT_EQ(limited, 4);
}

TEST(Queries, AGroundQueryFarFromEveryViewLoadsItsTerrainAFewChunksAtATime) {
  test::ServerProcess server({"--in-memory"});
  auto c = player(server, "scout");
  // 100,000 voxels out, from 480 above: the column's 17 chunks are loaded as the ray goes.
  wire::QueryResult r;
  int tries = 0;
  for (; tries < 40; ++tries) {
    r = ask(*c, ground(static_cast<uint64_t>(tries + 1), 100000.5f, -70000.5f, 480, 512));
    if (r.status() != wire::QueryResult::SERVER_BUSY) break;
    EXPECT_EQ(r.retry_after_ms(), 50u);
    EXPECT_NE(r.reason().find("ask again"), std::string::npos) << r.reason();
  }
  ASSERT_EQ(r.status(), wire::QueryResult::OK) << r.reason();
  EXPECT_GE(tries, 1);  // its first answer: 16 chunks loaded, ask again
  ASSERT_TRUE(r.hit());
  EXPECT_NEAR(r.point().y(), test::surface_y(100000.5f, -70000.5f), 3.0f);
}

}  // namespace
}  // namespace vox::net
