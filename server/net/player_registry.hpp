// Which connection holds each authenticated player id, and the player's edit budget: a
// second connection with the same id replaces the first (docs/PROTOCOL.md §4.8), so one
// player cannot be in the world twice nor keep a stale connection that a reconnect would
// have to wait out; every connection of the id shares one budget.
//
// Bounded: one entry per connected player (--max-clients), plus players who left while
// their budget was not full; those go once it has refilled (swept as entries are added),
// and all of them past `max_idle`. Any thread (one leaf mutex; the budget's own mutex is
// taken under it; no callback runs under it).
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "server/net/edit_budget.hpp"

namespace vox::net {

template <typename Session>
class PlayerRegistry {
 public:
  using Clock = std::chrono::steady_clock;
  explicit PlayerRegistry(size_t max_idle = 4096) : max_idle_(max_idle) {}

  struct Claim {
    std::shared_ptr<Session> previous;  // the connection that held the id, still alive
    std::shared_ptr<SharedEditBudget> budget;
  };
  // `session` now holds `player_id`, with a budget of `limits` (the player's existing one
  // when it has one, given these limits). The caller tells `previous` to go.
  Claim claim(const std::string& player_id, const std::shared_ptr<Session>& session,
              BudgetLimits limits, Clock::time_point now = Clock::now()) {
    std::lock_guard lock(mutex_);
    if (entries_.size() >= sweep_at_) sweep(now);
    Entry& e = entries_[player_id];
    Claim c;
    c.previous = e.holder.lock();
    if (c.previous == session) c.previous = nullptr;
    e.holder = session;
    if (e.budget)
      e.budget->set_limits(limits, now);
    else
      e.budget = std::make_shared<SharedEditBudget>(limits, now);
    c.budget = e.budget;
    return c;
  }
  // `session` ends: the id is free again, unless another session claimed it since. The
  // budget stays until it has refilled.
  void release(const std::string& player_id, const Session* session,
               Clock::time_point now = Clock::now()) {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(player_id);
    if (it == entries_.end()) return;
    const std::shared_ptr<Session> holder = it->second.holder.lock();
    if (holder && holder.get() != session) return;
    it->second.holder.reset();
    if (it->second.budget->full(now)) entries_.erase(it);
  }
  size_t size() const {  // entries, connected or not
    std::lock_guard lock(mutex_);
    return entries_.size();
  }

 private:
  struct Entry {
    std::weak_ptr<Session> holder;
    std::shared_ptr<SharedEditBudget> budget;
  };
  // Drops entries without a connection whose budget refilled; past max_idle of them, all
  // entries without a connection (their players get a fresh budget).
  void sweep(Clock::time_point now) {
    size_t idle = 0;
    for (auto it = entries_.begin(); it != entries_.end();) {
      const bool gone = it->second.holder.expired();
      if (gone && it->second.budget->full(now)) {
        it = entries_.erase(it);
        continue;
      }
      idle += gone ? 1 : 0;
      ++it;
    }
    if (idle > max_idle_) {
      for (auto it = entries_.begin(); it != entries_.end();)
        it = it->second.holder.expired() ? entries_.erase(it) : std::next(it);
    }
    sweep_at_ = 2 * entries_.size() + 64;
  }

  mutable std::mutex mutex_;
  const size_t max_idle_;
  size_t sweep_at_ = 64;
  std::unordered_map<std::string, Entry> entries_;
};

}  // namespace vox::net
