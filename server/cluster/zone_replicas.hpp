// The zones a cluster node follows without holding them (docs/CLUSTER.md, "Replicas and
// meshes"): those its players view. Each is followed by a ZoneFollower (NATS first, gaps
// filled from the zone's log), whose records wait here, in order, until the pipeline
// applies them to the node's world with the same code the owner used; the node then
// meshes its players' chunks itself. A zone not viewed for `idle` stops being followed
// (its chunks stay at the last record applied; following again resumes from there). At
// most `max_zones` are followed at once (each costs a thread and a database connection);
// past that the least recently viewed waits its turn. Records waiting are bounded per
// zone: a follower whose records the pipeline has not taken waits for it.
//
// Threads: `viewing` from any thread (cheap); `reconcile` from one thread (the keeper's
// round); `take` and `forget_through` from the pipeline thread; the followers' threads
// only queue. Destroying it stops every follower.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "server/cluster/nats_link.hpp"
#include "server/cluster/zone_follower.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

class ZoneReplicas {
 public:
  using Clock = std::chrono::steady_clock;
  struct Config {
    std::string world, uri, node;
    size_t max_zones = 32;
    std::chrono::milliseconds idle{std::chrono::minutes(5)};
    size_t max_waiting = 4096;  // records per zone waiting for the pipeline
  };
  // `wake`: records wait (any thread).
  ZoneReplicas(NatsLink& nats, Config config, std::function<void()> wake);
  ~ZoneReplicas();
  ZoneReplicas(const ZoneReplicas&) = delete;
  ZoneReplicas& operator=(const ZoneReplicas&) = delete;

  // A player views `zone` now; true when it was not viewed within `idle` (not followed)
  // and fewer than `max_zones` are followed: the caller has reconcile run soon, since the
  // view shows no records of it until then.
  bool viewing(world::ZoneId zone);
  // Starts following the zones viewed lately and not held (`held`), from the record after
  // `applied(zone)`; stops following held ones and those idle. Followers that cannot start
  // (the database or NATS down) are tried again next time.
  void reconcile(const std::function<bool(world::ZoneId)>& held,
                 const std::function<uint64_t(world::ZoneId)>& applied);
  // Up to `max` waiting records of one zone, in order, after `applied(zone)` (older ones
  // are dropped: the node applied them otherwise; so are those of zones `held` now, whose
  // records the node writes itself); nullopt when none wait. Zones take turns: the first
  // waiting after the zone taken last (one whose records cannot be applied now, and are
  // given back, holds up no other).
  struct Taken {
    world::ZoneId zone;
    std::vector<store::ZoneRecord> records;
  };
  std::optional<Taken> take(size_t max, const std::function<bool(world::ZoneId)>& held,
                            const std::function<uint64_t(world::ZoneId)>& applied);
  // Hands back records the pipeline could not apply (memory), to be taken again first: the
  // queue stays in sequence order, each record once.
  void give_back(world::ZoneId zone, std::vector<store::ZoneRecord> records);
  // The zones whose following started since the last call (the pipeline installs their
  // checkpoints when its world should: a follower starts after it, see ZoneFollower), and
  // one handed back when that could not be done now.
  std::vector<world::ZoneId> take_started();
  void started_again(world::ZoneId zone);
  bool waiting() const;
  bool following(world::ZoneId zone) const;  // any thread
  // Viewed within `idle` (followed, or waiting for a follower to start): any thread.
  bool viewed_lately(world::ZoneId zone) const;
  // Stops every follower, for good (reconcile's thread, or once that thread has ended):
  // after it no record arrives and `wake` is not called again.
  void stop();
  size_t followed() const { return followed_.load(std::memory_order_relaxed); }

 private:
  void stop_follower(world::ZoneId zone);  // reconcile's thread

  NatsLink& nats_;
  const Config config_;
  const std::function<void()> wake_;
  mutable std::mutex mutex_;  // guards viewed_, waiting_, stopping_, started_ (leaf)
  std::condition_variable taken_;
  std::map<world::ZoneId, Clock::time_point> viewed_;  // bounded: idle ones are dropped
  std::map<world::ZoneId, std::deque<store::ZoneRecord>> waiting_;
  std::map<world::ZoneId, bool> stopping_;   // a follower being stopped: its queue is not waited on
  std::set<world::ZoneId> started_;          // followed since the pipeline last looked
  std::optional<world::ZoneId> taken_last_;  // take's turns
  std::map<world::ZoneId, std::unique_ptr<ZoneFollower>> followers_;  // reconcile's thread
  std::atomic<size_t> followed_{0};
  bool stopped_ = false;         // reconcile's thread
  Clock::time_point warned_at_;  // likewise: the last "cannot follow" line
};

}  // namespace vox::cluster
