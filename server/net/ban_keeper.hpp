// The owner of the bans (docs/PROTOCOL.md 4.11): the book Hello is checked against, the
// world store's table behind it, and a thread that writes admins' bans to the store and
// reads the table back every `reload_every` (so a ban made on another node of a cluster
// world, or by hand, takes effect here). Without a store (--in-memory) the bans last
// until the process stops.
//
// Threads: match, page, size, put, remove and reload from any thread; `done` and the
// new-bans callback run on the keeper's thread (or, after stop, on the caller's). start
// and stop on one thread, stop before the callback's target goes.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include "server/net/ban_book.hpp"

namespace vox::net {

class BanKeeper {
 public:
  using Ban = store::Ban;
  struct Outcome {
    enum class Status { kOk, kNotFound, kTooMany, kUnavailable, kBusy, kStopped };
    Status status = Status::kOk;
    std::string message;  // why, when not kOk
    Ban ban;              // put: as stored; remove: the ban removed
  };
  using Done = std::function<void(const Outcome&)>;
  // Bans a reload found that were not in force before (their players are to be closed).
  using OnNewBans = std::function<void(const std::vector<Ban>&)>;

  static constexpr size_t kMaxQueued = 64;  // admin commands waiting for the store

  // With a store, reads its bans now: StoreError when it cannot (voxeld does not start).
  explicit BanKeeper(std::unique_ptr<store::BanStore> store = nullptr,
                     std::chrono::milliseconds reload_every = std::chrono::seconds(10));
  ~BanKeeper();  // stop()
  BanKeeper(const BanKeeper&) = delete;
  BanKeeper& operator=(const BanKeeper&) = delete;

  void start(OnNewBans on_new);
  void stop();  // waiting commands are answered kStopped; idempotent

  std::optional<Ban> match(const std::string& player_id, const std::string& address) const;
  BanBook::Page page(const std::string& cursor, size_t max) const;
  size_t size() const;
  bool stored() const { return store_ != nullptr; }
  // Stores `b` (replacing a ban of its target), then it is in force here.
  void put(Ban b, Done done);
  void remove(Ban::Kind kind, std::string target, Done done);
  void reload();  // reads the store's table now (SIGHUP)

  static int64_t now_ms();

 private:
  struct Job {
    bool put = false;
    Ban ban;  // put: the ban; remove: kind and target
    Done done;
  };
  void submit(Job job);
  void run();                           // the keeper's thread
  void apply(Job& job);                 // the keeper's thread
  void read_store(bool log_unchanged);  // the keeper's thread (and the constructor)

  const std::unique_ptr<store::BanStore> store_;
  const std::chrono::milliseconds reload_every_;
  OnNewBans on_new_;

  mutable std::mutex mutex_;  // leaf lock: book_, jobs_, the flags; no I/O under it
  std::condition_variable wake_;
  BanBook book_;
  std::deque<Job> jobs_;
  bool reload_now_ = false, stopping_ = false, started_ = false;
  std::thread thread_;
};

// "banned until 2026-12-08 10:00 UTC: griefing", "banned: griefing" (no end): what a
// banned player is told.
std::string describe_ban(const store::Ban& b);

}  // namespace vox::net
