// The session's pure policies: token buckets, admission, log rate limits and escaping,
// result ordering.
#include <gtest/gtest.h>

#include "server/net/admission_control.hpp"
#include "server/net/log_hygiene.hpp"
#include "server/net/player_registry.hpp"
#include "server/net/result_order.hpp"
#include "server/pipeline/token_bucket.hpp"

namespace vox::net {
namespace {

using pipeline::TokenBucket;

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// A player who connects again replaces the old connection; the old one ending later must
// not remove the new one's entry.
TEST(PlayerRegistry, ANewConnectionReplacesTheOldAndTheOldOneEndingKeepsIt) {
  struct Session {};
  PlayerRegistry<Session> players;
  auto first = std::make_shared<Session>(), second = std::make_shared<Session>();
  auto claim = [&players](const std::string& id, const std::shared_ptr<Session>& s) {
    return players.claim(id, s, BudgetLimits{}).previous;
  };
  EXPECT_EQ(claim("alice", first), nullptr);
  EXPECT_EQ(claim("alice", first), nullptr);  // the same connection again
  EXPECT_EQ(claim("alice", second), first);
  players.release("alice", first.get());
  EXPECT_EQ(players.size(), 1u);
  EXPECT_EQ(claim("bob", first), nullptr);
  players.release("alice", second.get());
  players.release("bob", first.get());
  EXPECT_EQ(players.size(), 0u);
  // An entry whose connection is gone is replaced without a word.
  auto gone = std::make_shared<Session>();
  claim("carol", gone);
  gone.reset();
  EXPECT_EQ(claim("carol", second), nullptr);
}

// Every connection of one player spends one budget: a reconnect brings no fresh burst,
// and the budget outlives the connection until it has refilled.
TEST(PlayerRegistry, AllConnectionsOfAPlayerShareOneEditBudgetUntilItRefills) {
  struct Session {};
  PlayerRegistry<Session> players;
  const auto t0 = Clock::now();
  const BudgetLimits limits{1000, 2000};
  auto first = std::make_shared<Session>();
  auto a = players.claim("alice", first, limits, t0).budget;
  EXPECT_EQ(a->take(2000, t0).count(), 0);
  players.release("alice", first.get(), t0);
  first.reset();
  EXPECT_EQ(players.size(), 1u) << "kept: not refilled";
  auto second = std::make_shared<Session>();
  auto b = players.claim("alice", second, limits, t0 + 500ms).budget;
  EXPECT_EQ(a, b);
  EXPECT_EQ(b->take(1000, t0 + 500ms), 500ms) << "only 500 samples back after 0.5 s";
  auto bob = players.claim("bob", first = std::make_shared<Session>(), limits, t0).budget;
  EXPECT_NE(bob, b) << "another player, another budget";
  players.release("alice", second.get(), t0 + 10s);
  EXPECT_EQ(players.size(), 1u) << "a refilled budget goes with its last connection";
}

// Idle entries (players gone, budgets not yet refilled) are bounded.
TEST(PlayerRegistry, IdleBudgetsAreSweptOnceRefilledAndCappedInNumber) {
  struct Session {};
  PlayerRegistry<Session> players(/*max_idle=*/100);
  const auto t0 = Clock::now();
  for (int i = 0; i < 1000; ++i) {
    auto s = std::make_shared<Session>();
    const std::string id = std::to_string(i) + "p";  // (GCC 12 -Wrestrict misfires on "p" + ...)
    players.claim(id, s, {1000, 2000}, t0).budget->take(1500, t0);  // leaves it not full
    players.release(id, s.get(), t0);
  }
  EXPECT_LE(players.size(), 2 * 100u + 64) << "past max_idle, idle entries are dropped";
  auto s = std::make_shared<Session>();
  for (int i = 0; i < 300; ++i) players.claim(std::to_string(i) + "q", s, {1000, 2000}, t0 + 10s);
  EXPECT_LE(players.size(), 300u + 64) << "refilled ones are swept";
}

TEST(EditBudgetPolicy, RoleDefaultsAndTokenOverrides) {
  const EditBudgetPolicy policy({300000, 600000}, {0, 0});
  using auth::Role;
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 0, 0, 1e5), (BudgetLimits{300000, 600000}));
  EXPECT_EQ(policy.limits_for(Role::kAdmin, 0, 0, 1e5), (BudgetLimits{0, 0})) << "unlimited";
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 50000, 0, 1e5), (BudgetLimits{50000, 100000}));
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 10000, 0, 1e5), (BudgetLimits{10000, 1e5}))
      << "a burst never below the largest edit";
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 10000, 400000, 1e5), (BudgetLimits{10000, 400000}));
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 10000, 5000, 1e5), (BudgetLimits{10000, 1e5}))
      << "a token's burst below the largest edit would refuse it for ever";
  EXPECT_EQ(policy.limits_for(Role::kPlayer, 0, 900000, 1e5), (BudgetLimits{300000, 900000}));
  EXPECT_EQ(policy.limits_for(Role::kAdmin, 0, 900000, 1e5), (BudgetLimits{0, 0}))
      << "a burst alone does not limit an unlimited role";
}

TEST(TokenBucket, TakesWithinTheBurstThenSaysHowLongToWait) {
  const auto t0 = Clock::now();
  TokenBucket b(1000, 3000, t0);
  EXPECT_EQ(b.take(2000, t0).count(), 0);
  const auto wait = b.take(2000, t0);
  EXPECT_EQ(wait, 1000ms) << "1,000 tokens missing at 1,000/s";
  EXPECT_EQ(b.take(2000, t0 + 1s).count(), 0) << "refilled";
  EXPECT_EQ(b.take(5000, t0 + 100s), std::chrono::milliseconds::max()) << "over the burst: never";
  EXPECT_LE(b.tokens(t0 + 100s), 3000) << "never above the burst";
}

TEST(TokenBucket, ZeroRateIsUnlimited) {
  TokenBucket b(0, 0);
  for (int i = 0; i < 1000; ++i) EXPECT_EQ(b.take(1e9, Clock::now()).count(), 0);
}

TEST(AdmissionControl, HandshakingConnectionsDoNotCountAsPlayersButHaveTheirOwnCap) {
  AdmissionControl a({.max_players = 2,
                      .max_handshaking = 3,
                      .max_per_address = 0,
                      .max_handshaking_per_address = 0});
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(a.connect("10.0.0." + std::to_string(i)), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("10.0.0.9"), AdmissionControl::Verdict::kHandshakesFull);
  EXPECT_EQ(a.promote("10.0.0.0"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.promote("10.0.0.1"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.promote("10.0.0.2"), AdmissionControl::Verdict::kServerFull) << "a third player";
  EXPECT_EQ(a.handshaking(), 1u) << "the refused one holds its handshake slot until it closes";
  EXPECT_EQ(a.connect("10.0.0.8"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("10.0.0.9"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("10.0.0.10"), AdmissionControl::Verdict::kHandshakesFull);
  a.release("10.0.0.2", false);
  EXPECT_EQ(a.connect("10.0.0.10"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.players(), 2u);
  EXPECT_EQ(a.handshaking(), 3u);
}

TEST(AdmissionControl, OneAddressCannotFillTheServer) {
  AdmissionControl a({.max_players = 100,
                      .max_handshaking = 100,
                      .max_per_address = 4,
                      .max_handshaking_per_address = 0});
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAddressFull);
  EXPECT_EQ(a.connect("5.6.7.8"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.promote("1.2.3.4"), AdmissionControl::Verdict::kAdmit);
  a.release("1.2.3.4", true);
  EXPECT_EQ(a.connections_from("1.2.3.4"), 3u);
  EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAdmit);
  for (int i = 0; i < 4; ++i) a.release("1.2.3.4", false);
  EXPECT_EQ(a.connections_from("1.2.3.4"), 0u);
}

TEST(AdmissionControl, AFewAddressesCannotHoldEveryHandshakeSlot) {
  AdmissionControl a({.max_players = 100,
                      .max_handshaking = 64,
                      .max_per_address = 16,
                      .max_handshaking_per_address = 4});
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAddressFull) << "a fifth silent one";
  EXPECT_EQ(a.promote("1.2.3.4"), AdmissionControl::Verdict::kAdmit);
  EXPECT_EQ(a.connect("1.2.3.4"), AdmissionControl::Verdict::kAdmit)
      << "players free handshake slots";
  EXPECT_EQ(a.handshaking(), 4u);
}

TEST(LogHygiene, EscapesEverythingThatCouldForgeALine) {
  EXPECT_EQ(escape_for_log("alice"), "alice");
  EXPECT_EQ(escape_for_log("a\nb"), "a\\x0ab");
  EXPECT_EQ(escape_for_log("\r\t\x1b[31m'\"\\"), "\\x0d\\x09\\x1b[31m\\x27\\x22\\x5c");
  EXPECT_EQ(escape_for_log("\xc3\xa9"), "\\xc3\\xa9");
  EXPECT_EQ(escape_for_log(std::string(100, 'x'), 8), "xxxxxxxx...");
}

TEST(LogHygiene, AtMostOneLineASecondPerKindWithTheSuppressedCount) {
  LogRateLimit limit(1s);
  const auto t0 = Clock::now();
  EXPECT_EQ(limit.allow("UNKNOWN_MESSAGE", t0), 0u);
  for (int i = 0; i < 999; ++i) EXPECT_FALSE(limit.allow("UNKNOWN_MESSAGE", t0 + 1ms * i));
  EXPECT_EQ(limit.allow("BAD_VALUE", t0), 0u) << "kinds are limited separately";
  EXPECT_EQ(limit.allow("UNKNOWN_MESSAGE", t0 + 1s), 999u);
  EXPECT_EQ(limit.allow("joined", t0, 3), 0u);
  EXPECT_EQ(limit.allow("joined", t0, 3), 0u);
  EXPECT_EQ(limit.allow("joined", t0, 3), 0u);
  EXPECT_FALSE(limit.allow("joined", t0, 3));
}

TEST(ResultOrder, ARefusalWaitsBehindEarlierEditsStillInThePipeline) {
  ResultOrder order;
  std::vector<uint64_t> sent;
  auto result = [](uint64_t id) {
    wire::Envelope e;
    e.mutable_edit_result()->set_request_id(id);
    return e;
  };
  auto out = [&sent](const wire::Envelope& e) { sent.push_back(e.edit_result().request_id()); };
  const uint64_t first = order.reserve();
  const uint64_t second = order.reserve();
  order.push_ready(result(3));
  order.drain(out);
  EXPECT_TRUE(sent.empty());
  order.fill(second, result(2));
  order.drain(out);
  EXPECT_TRUE(sent.empty());
  order.fill(first, result(1));
  order.drain(out);
  EXPECT_EQ(sent, (std::vector<uint64_t>{1, 2, 3}));
  EXPECT_EQ(order.size(), 0u);
}

TEST(ResultOrder, VersionsFromTheOldestEditStillInThePipelineMayNotBeSent) {
  ResultOrder order;
  EXPECT_EQ(order.first_unsendable_version(), ResultOrder::kNoLimit);
  const uint64_t first = order.reserve(10);  // newest published was 9 when it was submitted
  const uint64_t second = order.reserve(14);
  EXPECT_EQ(order.first_unsendable_version(), 10u);
  auto noop = [](const wire::Envelope&) {};
  order.fill(first, {});
  order.drain(noop);
  EXPECT_EQ(order.first_unsendable_version(), 14u);
  order.push_ready({});  // a refusal makes no version
  order.fill(second, {});
  order.drain(noop);
  EXPECT_EQ(order.first_unsendable_version(), ResultOrder::kNoLimit);
}

}  // namespace
}  // namespace vox::net
