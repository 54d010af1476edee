// QueryGate (server/net/query_gate.hpp): each rule a query meets before the pipeline.
#include "server/net/query_gate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace vox::net {
namespace {

using Clock = QueryGate::Clock;

wire::Query ray(std::array<float, 3> from, std::array<float, 3> dir, float max) {
  wire::Query q;
  auto* r = q.mutable_raycast();
  r->mutable_origin()->set_x(from[0]), r->mutable_origin()->set_y(from[1]);
  r->mutable_origin()->set_z(from[2]);
  r->mutable_direction()->set_x(dir[0]), r->mutable_direction()->set_y(dir[1]);
  r->mutable_direction()->set_z(dir[2]);
  r->set_max_distance(max);
  return q;
}

wire::Query box(std::array<int32_t, 3> lo, std::array<int32_t, 3> hi) {
  wire::Query q;
  auto* b = q.mutable_samples()->mutable_box();
  b->set_min_x(lo[0]), b->set_min_y(lo[1]), b->set_min_z(lo[2]);
  b->set_max_x(hi[0]), b->set_max_y(hi[1]), b->set_max_z(hi[2]);
  return q;
}

TEST(QueryGate, AValidRayIsNormalisedAndCutAtTheWorldsEdge) {
  pipeline::QueryTask task;
  EXPECT_EQ(QueryGate::check(ray({1, 2, 3}, {0, -4, 3}, 100), {}, {}, task), "");
  ASSERT_TRUE(task.ray);
  EXPECT_FLOAT_EQ(task.ray->direction.y, -0.8f);
  EXPECT_FLOAT_EQ(task.ray->direction.z, 0.6f);
  EXPECT_FLOAT_EQ(task.ray->max_distance, 100);
  // 4,095 is the top sample: a ray up from 4,000 ends there.
  pipeline::QueryTask up;
  EXPECT_EQ(QueryGate::check(ray({0, 4000, 0}, {0, 1, 0}, 500), {}, {}, up), "");
  EXPECT_FLOAT_EQ(up.ray->max_distance, 95);
  // A ground query is a ray down.
  wire::Query g;
  g.mutable_ground()->set_x(5), g.mutable_ground()->set_z(6);
  g.mutable_ground()->set_from_y(50), g.mutable_ground()->set_max_depth(30);
  pipeline::QueryTask down;
  EXPECT_EQ(QueryGate::check(g, {}, {}, down), "");
  EXPECT_FLOAT_EQ(down.ray->direction.y, -1);
  EXPECT_FLOAT_EQ(down.ray->origin.x, 5);
}

TEST(QueryGate, EveryBadValueIsRefusedWithAReason) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<wire::Query> bad = {
      ray({nan, 0, 0}, {0, 1, 0}, 5),
      ray({0, 0, 0}, {0, 0, 0}, 5),
      ray({0, 0, 0}, {1e-7f, 0, 0}, 5),
      ray({0, 0, 0}, {0, 1, 0}, 0),
      ray({0, 0, 0}, {0, 1, 0}, 513),
      ray({0, 4096, 0}, {0, -1, 0}, 5),     // above the top sample
      ray({-1048577, 0, 0}, {1, 0, 0}, 5),  // west of the world
      box({0, 0, 0}, {32, 31, 31}),         // 33 x 32 x 32
      box({0, 1, 0}, {0, 0, 0}),            // min above max
      box({0, 4095, 0}, {0, 4096, 0}),      // past the top
      box({INT32_MIN, 0, 0}, {INT32_MIN, 0, 0}),
      box({0, 0, 0}, {INT32_MAX, INT32_MAX, INT32_MAX}),
      wire::Query{},  // none
  };
  for (size_t i = 0; i < bad.size(); ++i) {
    pipeline::QueryTask task;
    EXPECT_NE(QueryGate::check(bad[i], {}, {}, task), "") << i;
  }
  pipeline::QueryTask task;
  EXPECT_EQ(QueryGate::check(box({0, 0, 0}, {31, 31, 31}), {}, {}, task), "");  // 32^3 fits
}

TEST(QueryGate, WaitingQueriesAreCappedAndAnAnswerFreesAPlace) {
  const auto now = Clock::now();
  QueryGate gate({}, QueryLimits{.max_in_flight = 2, .rate = 0}, now);
  pipeline::QueryTask t;
  EXPECT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now));
  EXPECT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now));
  const auto third = gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now);
  ASSERT_TRUE(third);
  EXPECT_EQ(third->status, wire::QueryResult::TOO_MANY);
  gate.answered();
  EXPECT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now));
  // A refused query takes no place.
  gate.answered();
  EXPECT_TRUE(gate.admit(wire::Query{}, t, now));
  EXPECT_EQ(gate.in_flight(), 1u);
}

TEST(QueryGate, OverTheRateTheRefusalSaysWhenToAskAgain) {
  const auto now = Clock::now();
  QueryGate gate({}, QueryLimits{.max_in_flight = 100, .rate = 10}, now);  // burst 20
  pipeline::QueryTask t;
  for (int i = 0; i < 20; ++i) ASSERT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now)) << i;
  const auto over = gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now);
  ASSERT_TRUE(over);
  EXPECT_EQ(over->status, wire::QueryResult::RATE_LIMITED);
  EXPECT_EQ(over->retry_after_ms, 100u);
  EXPECT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now + std::chrono::milliseconds(100)));
}

TEST(QueryGate, ARateBelowHalfAQueryASecondStillLetsOneThrough) {
  const auto now = Clock::now();
  QueryGate gate({}, QueryLimits{.rate = 0.2}, now);  // the burst is never below one query
  pipeline::QueryTask t;
  EXPECT_FALSE(gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now));
  const auto next = gate.admit(box({0, 0, 0}, {1, 1, 1}), t, now);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->retry_after_ms, 5000u);
}

TEST(QueryGate, AClusterWorldRefusesQueries) {
  QueryGate gate({}, QueryLimits{.cluster = true});
  pipeline::QueryTask t;
  const auto r = gate.admit(box({0, 0, 0}, {1, 1, 1}), t, Clock::now());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, wire::QueryResult::BAD_VALUE);
  EXPECT_EQ(gate.in_flight(), 0u);
}

}  // namespace
}  // namespace vox::net
