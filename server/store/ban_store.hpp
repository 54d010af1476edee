// The world's bans (docs/PROTOCOL.md 4.11): a player id or an address kept out until a
// time, stored beside the world so they survive restarts and, on PostgreSQL, are shared
// by every node of a cluster world. Its own connection: one thread at a time (the
// server's BanKeeper); every failure a StoreError naming the store, and a later call
// tries again (PostgreSQL reconnects).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "server/store/world_store.hpp"

namespace vox::store {

struct Ban {
  enum class Kind : uint8_t { kPlayer, kAddress };
  Kind kind = Kind::kPlayer;
  std::string target;      // the player id, or the address as admission counts it
  std::string reason;      // at most kMaxBanReason bytes, no control characters
  std::string created_by;  // the admin's player id
  int64_t created_ms = 0;  // Unix milliseconds
  int64_t until_ms = 0;    // when it ends (0: never)

  bool expired(int64_t now_ms) const { return until_ms != 0 && until_ms <= now_ms; }
  friend bool operator==(const Ban&, const Ban&) = default;
};

inline constexpr size_t kMaxBans = 100000;    // a world's bans at most
inline constexpr size_t kMaxBanReason = 200;  // bytes
inline constexpr size_t kMaxBanTarget = 128;  // bytes of a player id or address

const char* to_string(Ban::Kind kind);  // "player", "address"
// Why `b` cannot be stored (an empty or oversized target, reason or author, a control
// character), or nullopt.
std::optional<std::string> ban_problem(const Ban& b);

class BanStore {
 public:
  virtual ~BanStore() = default;
  virtual const std::string& name() const = 0;
  struct Read {
    std::vector<Ban> bans;  // valid and unexpired, at most kMaxBans
    size_t skipped = 0;     // rows that are not a valid ban (kept, never used)
    size_t over = 0;        // valid bans past kMaxBans (kept, never used)
  };
  // Every ban in force at `now_ms`; deletes those that ended (only when one did: a read
  // takes no write lock otherwise). An address as the row has it: the caller checks its
  // form.
  virtual Read read(int64_t now_ms) = 0;
  virtual void put(const Ban& b) = 0;  // adds, or replaces the ban of the same target
  // False when there was no ban of that target.
  virtual bool remove(Ban::Kind kind, const std::string& target) = 0;
};

// `where`: a world directory (SQLite: the table lives in its world.sqlite, which must
// exist) or a postgresql:// URI; `world`: a cluster world's name (its nodes share the
// database's table), empty for a single node's.
std::unique_ptr<BanStore> open_ban_store(const std::string& where, const std::string& world = "");

}  // namespace vox::store
