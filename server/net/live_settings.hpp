// What a SIGHUP may change while voxeld runs (the README, "Reloading the configuration"):
// the key player tokens are checked with and the edit budgets of the roles, read at each
// Hello (and given to the players already in: ClientSession::reload_budget). Any thread
// (one leaf mutex).
#pragma once

#include <mutex>
#include <optional>

#include "server/auth/player_token.hpp"

namespace vox::net {

struct LiveValues {
  std::optional<auth::PublicKey> auth_key;  // none: an open server (fixed at start)
  double edit_budget_rate = 0, edit_budget_burst = 0;
  double admin_edit_budget_rate = 0, admin_edit_budget_burst = 0;
};

class LiveSettings {
 public:
  explicit LiveSettings(LiveValues values) : values_(std::move(values)) {}
  LiveValues get() const {
    std::lock_guard lock(mutex_);
    return values_;
  }
  void set(LiveValues values) {
    std::lock_guard lock(mutex_);
    values_ = std::move(values);
  }

 private:
  mutable std::mutex mutex_;  // leaf lock
  LiveValues values_;
};

}  // namespace vox::net
