// The bans in force, in memory, as the world store holds them (store/ban_store.hpp): what
// Hello is checked against, and the pages of an admin's ban list. At most kMaxBans. Not
// thread-safe: its owner (BanKeeper) guards it.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/store/ban_store.hpp"

namespace vox::net {

class BanBook {
 public:
  using Ban = store::Ban;
  // The ban of `player_id` (when not empty), else of `address`, in force at `now_ms`.
  std::optional<Ban> match(const std::string& player_id, const std::string& address,
                           int64_t now_ms) const;
  // Adds or replaces the ban of b's target; false (nothing changed) when that would make
  // more than kMaxBans.
  bool put(Ban b);
  bool contains(Ban::Kind kind, const std::string& target) const {
    return bans_.contains({kind, target});
  }
  std::optional<Ban> remove(Ban::Kind kind, const std::string& target);
  // The book becomes `bans`; returns those in force now that were not before (to close
  // their players' connections).
  std::vector<Ban> replace(std::vector<Ban> bans, int64_t now_ms);
  void drop_ended(int64_t now_ms);
  size_t size() const { return bans_.size(); }

  // A page of at most `max` bans in force, in (kind, target) order, after `cursor` (empty:
  // from the start); `next` is the cursor of the page after it, empty at the end.
  struct Page {
    std::vector<Ban> bans;
    std::string next;
  };
  Page page(const std::string& cursor, size_t max, int64_t now_ms) const;

 private:
  using Key = std::pair<Ban::Kind, std::string>;
  static std::string cursor_of(const Key& k);
  std::map<Key, Ban> bans_;
};

}  // namespace vox::net
