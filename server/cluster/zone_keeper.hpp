// A node's zones over time (docs/CLUSTER.md): a thread that every lease / 3 renews the
// node's heartbeat, reads the live nodes and runs plan_zones: it renews the zones it
// keeps, hands off those another node now ranks first for, and takes those it was asked
// for and ranks first for.
//
// Callbacks run on the keeper's thread and must not block long: `taken(zone, epoch)` once
// a zone is this node's; `lost(zone, epoch)` when it stops being: a renewal refused
// (another node took it after this one's lease ran out), a hand-off (before the
// release), or no renewal for a whole lease by this node's clock (the database out of
// reach: this node can no longer tell whether it still owns it). The caller stops
// serving a lost zone at once; its late writes would be fenced anyway. While another
// live process's heartbeat holds the node id (two given the same id, or this one paused
// long enough for a restarted one to start), this one loses its zones and takes none.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

class ZoneKeeper {
 public:
  using Clock = std::chrono::steady_clock;
  struct Config {
    std::string uri;      // the cluster's PostgreSQL
    std::string node;     // this node's id: one live process's at a time
    std::string address;  // where players reach it, for the heartbeat row
    std::chrono::milliseconds lease{3000};
    size_t max_zones = size_t{1} << 16;  // zones asked for, remembered at once
  };
  struct Events {
    std::function<void(world::ZoneId, uint64_t epoch)> taken, lost;
    // After each round (about every lease / 3), with the keeper's connection for what
    // else the node reads then.
    std::function<void(store::ZoneLeases&)> round;
    // Released for another node: one ranking first now, or any, at a graceful stop.
    std::function<void(world::ZoneId)> handed_off;
    // A hand-off's first step, a moment before `lost`: take no more edits in the zone
    // (the appends made meanwhile still land under its epoch).
    std::function<void(world::ZoneId, uint64_t epoch)> leaving;
  };

  // Opens its connection (throws store::StoreError when the database cannot be reached)
  // and starts the thread.
  ZoneKeeper(Config config, Events events);
  ~ZoneKeeper();  // stop(false)
  ZoneKeeper(const ZoneKeeper&) = delete;
  ZoneKeeper& operator=(const ZoneKeeper&) = delete;

  // Any thread: this node should own `zone` if it ranks first; a zone not asked for before
  // starts a round at once (taken then when free). At most Config::max_zones are
  // remembered; asked for more, it refuses them (false).
  bool want(world::ZoneId zone);
  // Any thread: the next round starts at once (the node has new zones to follow).
  void poke();
  // Any thread: the epoch this node holds `zone` at; nullopt when it does not.
  std::optional<uint64_t> epoch_of(world::ZoneId zone) const;
  size_t held_count() const;  // any thread
  // Any thread: why this node should not take players now (a load balancer's health check,
  // docs/CLUSTER.md "Clients"), or nullopt: no round reached the database for a lease and
  // a half, or another live process holds the node id.
  std::optional<std::string> unhealthy() const;
  // Stops the thread: `release` lets every held zone go and takes this node out of the
  // live list first (a graceful shutdown: the next owners take its zones in their next
  // round), else they expire with their leases (what a crash does). Any thread but a
  // callback; idempotent.
  void stop(bool release);

 private:
  struct Held {
    uint64_t epoch = 0;
    Clock::time_point renewed;  // when the last successful renewal (or the take) started
  };
  void run();
  void round();

  const Config config_;
  const Events events_;
  struct Leases;  // the keeper thread's connection
  std::unique_ptr<Leases> leases_;
  mutable std::mutex mutex_;  // guards what follows; never held across the database
  std::condition_variable wake_;
  std::map<world::ZoneId, Held> held_;
  std::set<world::ZoneId> interest_;
  bool stopping_ = false, release_ = false, asked_ = false;
  // The keeper thread's alone: another process's heartbeat has this node id, since when,
  // and when that was last logged as an error.
  static constexpr std::chrono::milliseconds kLeastGap{50};
  static constexpr std::chrono::seconds kShadowLogEvery{60};
  bool shadowed_ = false;
  // For unhealthy(): the start of the last round that reached the database (steady clock
  // ticks), and whether another process holds the node id.
  std::atomic<Clock::rep> round_ok_at_{0};
  std::atomic<bool> shadowed_now_{false};
  Clock::time_point shadowed_since_{};
  std::optional<Clock::time_point> shadow_logged_;
  std::thread thread_;
};

}  // namespace vox::cluster
