// A player's edit budget: a token bucket of samples (an edit costs the samples its box
// touches) shared by every connection of one player id, so reconnecting or a second
// connection brings no fresh burst. Its limits come from the player's role, or from the
// token when the game's backend put limits in it (docs/PROTOCOL.md 4.8).
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <mutex>

#include "server/auth/player_token.hpp"
#include "server/pipeline/token_bucket.hpp"

namespace vox::net {

struct BudgetLimits {
  double rate = 0;   // samples per second; <= 0: unlimited
  double burst = 0;  // samples
  bool operator==(const BudgetLimits&) const = default;
};

// Pure policy: the limits of a player's edit budget.
class EditBudgetPolicy {
 public:
  // Per-role defaults (a viewer never edits).
  EditBudgetPolicy(BudgetLimits player, BudgetLimits admin) : player_(player), admin_(admin) {}
  // A token's edit_rate overrides its role's rate (and edit_burst its burst; without one,
  // two seconds of the token's rate). A burst is never below `min_burst`: the largest edit.
  BudgetLimits limits_for(auth::Role role, uint32_t token_rate, uint32_t token_burst,
                          double min_burst) const {
    BudgetLimits l = role == auth::Role::kAdmin ? admin_ : player_;
    if (token_rate > 0) {
      l.rate = token_rate;
      l.burst = token_burst > 0 ? token_burst : 2.0 * token_rate;
    } else if (token_burst > 0 && l.rate > 0) {
      l.burst = token_burst;
    }
    if (l.rate > 0) l.burst = std::max(l.burst, min_burst);  // the largest edit always fits
    return l;
  }

 private:
  BudgetLimits player_, admin_;
};

// The bucket behind a leaf mutex: any thread (the strands of a player's connections).
class SharedEditBudget {
 public:
  using Clock = std::chrono::steady_clock;
  explicit SharedEditBudget(BudgetLimits l, Clock::time_point now = Clock::now())
      : limits_(l), bucket_(l.rate, l.burst, now) {}

  std::chrono::milliseconds take(double cost, Clock::time_point now) {
    std::lock_guard lock(mutex_);
    return bucket_.take(cost, now);
  }
  std::chrono::milliseconds wait_for(double cost, Clock::time_point now) {
    std::lock_guard lock(mutex_);
    return bucket_.wait_for(cost, now);
  }
  void charge(double cost, Clock::time_point now) {
    std::lock_guard lock(mutex_);
    bucket_.charge(cost, now);
  }
  // A newer token's limits (the tokens held are kept, up to the new burst).
  void set_limits(BudgetLimits l, Clock::time_point now) {
    std::lock_guard lock(mutex_);
    if (l == limits_) return;
    limits_ = l;
    bucket_.set_limits(l.rate, l.burst, now);
  }
  BudgetLimits limits() const {
    std::lock_guard lock(mutex_);
    return limits_;
  }
  bool full(Clock::time_point now) {
    std::lock_guard lock(mutex_);
    return bucket_.full(now);
  }

 private:
  mutable std::mutex mutex_;  // leaf lock
  BudgetLimits limits_;
  pipeline::TokenBucket bucket_;
};

}  // namespace vox::net
