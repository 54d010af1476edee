// Follows one zone's committed records (docs/CLUSTER.md): subscribes to the zone's record
// and heartbeat subjects, reads the zone's log from PostgreSQL after what the caller's
// replica already holds, and hands the caller every later record once, in sequence
// order. A record that arrives ahead of its turn waits for the ones before it; a gap (a
// record lost, or a heartbeat newer than what was applied) is filled from the log after
// `gap_wait`, so a lost NATS message costs latency, never correctness. A replica that
// should install the zone's checkpoint (checkpoint_first) starts after it: the first record
// handed over is then not the next, and the caller installs the checkpoint. A message that
// does not decode or names another zone is dropped and counted, and so is a claim of a
// record the log does not have (records are published after commit). At most 10,000
// records or 16 MiB wait for their turn; past that they are read from the log.
//
// Threads: NATS handlers only queue; the follower's own thread reads the log and calls
// `apply`, one record at a time (apply must not call back into the follower). Any thread
// may read the counters. Destroying it stops the thread and the subscriptions.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "server/cluster/nats_link.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

// Whether a world that has a zone's records through `applied` installs the zone's
// checkpoint through `checkpoint_seq` rather than apply the records between: when it has
// none of them, or is far behind (docs/CLUSTER.md, "Zone checkpoints").
inline bool checkpoint_first(uint64_t applied, uint64_t checkpoint_seq) {
  constexpr uint64_t kFarBehind = 4096;  // records
  return checkpoint_seq > applied && (applied == 0 || checkpoint_seq - applied > kFarBehind);
}

class ZoneFollower {
 public:
  using Apply = std::function<void(const store::ZoneRecord&)>;
  struct Config {
    std::string world;  // the subjects' world name (valid_world_name)
    world::ZoneId zone;
    std::string uri;                         // the cluster's PostgreSQL, for the log
    std::string node;                        // this node's id (the log connection's)
    uint64_t applied = 0;                    // the replica holds every record up to this one
    std::chrono::milliseconds gap_wait{50};  // how long a gap may wait for NATS first
  };

  // Subscribes, then starts the thread (whose first act is reading the log). Throws
  // ClusterError or store::StoreError when it cannot subscribe or reach the database.
  ZoneFollower(NatsLink& nats, Config config, Apply apply);
  ~ZoneFollower();
  ZoneFollower(const ZoneFollower&) = delete;
  ZoneFollower& operator=(const ZoneFollower&) = delete;

  uint64_t applied() const { return applied_.load(std::memory_order_acquire); }
  uint64_t filled() const { return filled_.load(std::memory_order_relaxed); }    // from the log
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }  // bad messages

 private:
  void on_message(const NatsMessage& m);  // NATS threads
  void run();                             // the follower's thread
  // Reads the log after applied_, through `through`: reached it, the log ended short of
  // it, or the log could not be read (then it waited a little).
  enum class Fill { kReached, kShort, kFailed };
  Fill fill(uint64_t through);

  NatsLink& nats_;
  const Config config_;
  const Apply apply_;
  store::ZoneLeases log_;  // the thread's connection
  std::mutex mutex_;       // guards ahead_, ahead_bytes_, newest_, stopping_
  std::condition_variable wake_;
  std::map<uint64_t, store::ZoneRecord> ahead_;  // received, not applied yet (bounded)
  size_t ahead_bytes_ = 0;                       // their payloads
  uint64_t newest_ = 0;                          // the highest seq heard of
  bool stopping_ = false;
  std::atomic<uint64_t> applied_{0}, filled_{0}, dropped_{0};
  uint64_t records_sub_ = 0, heartbeat_sub_ = 0;
  std::thread thread_;
};

}  // namespace vox::cluster
