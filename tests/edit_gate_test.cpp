// The session's edit gate (server/net/edit_gate.hpp): each rule that refuses an edit at
// once, in its order, and the budget's debt for terrain an edit made the server generate.
#include "server/net/edit_gate.hpp"

#include <gtest/gtest.h>

namespace vox::net {
namespace {

using Clock = EditGate::Clock;

world::Edit explosion(float radius = 2) { return world::Explosion{{0, 0, 0}, radius, 1}; }

std::shared_ptr<SharedEditBudget> budget(double rate, double burst, Clock::time_point now) {
  return std::make_shared<SharedEditBudget>(BudgetLimits{rate, burst}, now);
}

TEST(EditGate, AViewerOrAClientBeforeHelloMayNotEdit) {
  EditGate gate({}, 4);
  const auto now = Clock::now();
  EXPECT_EQ(gate.admit(explosion(), now)->status, wire::EditResult::FORBIDDEN);
  gate.join(auth::Role::kViewer, budget(0, 0, now));
  const auto refused = gate.admit(explosion(), now);
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->status, wire::EditResult::FORBIDDEN);
  EXPECT_EQ(refused->reason, "a viewer may not edit");
  EXPECT_EQ(gate.in_flight(), 0u);
}

TEST(EditGate, ABadEditIsRefusedBeforeItCostsAnything) {
  EditGate gate({}, 4);
  const auto now = Clock::now();
  const auto player_budget = budget(1, 1e9, now);
  gate.join(auth::Role::kPlayer, player_budget);
  const auto refused = gate.admit(explosion(1e6f), now);  // a radius past the limit
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->status, wire::EditResult::BAD_RADIUS);
  EXPECT_EQ(gate.in_flight(), 0u);
  EXPECT_TRUE(player_budget->full(now));  // nothing taken
}

TEST(EditGate, EditsInFlightAreCappedUntilTheyAreAnswered) {
  EditGate gate({}, 2);
  const auto now = Clock::now();
  gate.join(auth::Role::kPlayer, budget(0, 0, now));  // unlimited
  EXPECT_FALSE(gate.admit(explosion(), now));
  EXPECT_FALSE(gate.admit(explosion(), now));
  const auto refused = gate.admit(explosion(), now);
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->status, wire::EditResult::TOO_MANY_EDITS);
  EXPECT_EQ(refused->reason, "over 2 edits still being applied");
  gate.answered(0, now);
  EXPECT_FALSE(gate.admit(explosion(), now));
}

TEST(EditGate, OverTheBudgetAnEditWaitsAndTerrainItMadeIsChargedAfterwards) {
  EditGate gate({}, 16);
  const auto now = Clock::now();
  const double one = EditGate::cost(explosion());
  gate.join(auth::Role::kPlayer, budget(one, one, now));  // one explosion a second
  EXPECT_FALSE(gate.admit(explosion(), now));
  const auto refused = gate.admit(explosion(), now);
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->status, wire::EditResult::RATE_LIMITED);
  EXPECT_GT(refused->retry_after_ms, 500u);
  EXPECT_LE(refused->retry_after_ms, 1000u);
  // The answer says it generated two chunks: debt the player waits out.
  gate.answered(2, now);
  EXPECT_GT(gate.rate_limited_retry_ms(now + std::chrono::seconds(1)), 0u);
  EXPECT_TRUE(gate.admit(explosion(), now + std::chrono::seconds(2)).has_value());
}

}  // namespace
}  // namespace vox::net
