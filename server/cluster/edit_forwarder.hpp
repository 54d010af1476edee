// A gateway's side of edits in zones another node holds (docs/CLUSTER.md, "Messaging over
// NATS"): each is sent as a NATS request on its zone's edit subject, whoever holds the
// zone answers once the edit is durable (or refused), and the answer comes back on this
// node's own reply subjects. A zone moving between nodes is waited for: nobody holding it
// (the server says so at once: `nobody_holds` asks the cluster to take it), or an answer
// that the zone is not writable there (handed off, or its log still being applied), sends
// the request again every `retry` until the timeout. No answer within the timeout:
// refused, saying the edit may have landed, and the cluster is asked to take the zone
// (its holder may be dead or stalled; the node ranking first among the live ones takes it
// once the holder's lease has run out); still moving at the timeout: refused (retry).
// At most `max_pending` wait at once (past that: SERVER_BUSY).
//
// Threads: forward from any thread; its own thread ("vox-forward") sends the retries and
// refuses what timed out; `done` runs on a NATS thread or that one (or the destructor's,
// which refuses what still waits).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "server/cluster/edit_wire.hpp"
#include "server/cluster/nats_link.hpp"

namespace vox::cluster {

class EditForwarder {
 public:
  using Clock = std::chrono::steady_clock;
  using Done = std::function<void(const EditReply&)>;
  struct Config {
    std::string world;
    std::chrono::milliseconds timeout{5000};
    std::chrono::milliseconds retry{50};  // a moving zone is asked again this often
    size_t max_pending = 4096;
  };
  // Subscribes to its reply subjects (throws ClusterError when it cannot).
  EditForwarder(NatsLink& nats, Config config, std::function<void(world::ZoneId)> nobody_holds);
  ~EditForwarder();
  EditForwarder(const EditForwarder&) = delete;
  EditForwarder& operator=(const EditForwarder&) = delete;

  // Sends `request` (its id is set here) to `zone`'s holder; `done` hears the answer.
  void forward(world::ZoneId zone, EditRequest request, Done done);
  size_t pending() const;
  // Counts since start (any thread): edits forwarded, refused for no holder, timed out.
  uint64_t forwarded() const { return forwarded_.load(std::memory_order_relaxed); }
  uint64_t unheld() const { return unheld_.load(std::memory_order_relaxed); }
  uint64_t timed_out() const { return timed_out_.load(std::memory_order_relaxed); }
  uint64_t retried() const { return retried_.load(std::memory_order_relaxed); }

 private:
  struct Pending {
    Done done;
    world::ZoneId zone;
    Clock::time_point deadline;
    std::vector<uint8_t> request;               // sent again while the zone moves
    std::optional<Clock::time_point> again_at;  // when, while it waits to be sent again
    std::optional<EditReply> moving;            // the last "not writable here" answer
    bool unheld = false;                        // the last send found no holder
  };
  void on_reply(const NatsMessage& m);  // NATS thread
  void run();                           // its thread: retries and timeouts
  void sweep();
  void send(world::ZoneId zone, uint64_t id, const std::vector<uint8_t>& request);
  static EditReply refusal(uint64_t id, world::RefusalReason reason, std::string message);
  static EditReply unheld_refusal(uint64_t id, world::ZoneId zone);

  NatsLink& nats_;
  const Config config_;
  const std::function<void(world::ZoneId)> nobody_holds_;
  const std::string inbox_;   // "_INBOX.<random>": replies come on <inbox>.<id>
  mutable std::mutex mutex_;  // guards pending_, next_id_ (leaf; never held across a callback)
  std::map<uint64_t, Pending> pending_;
  uint64_t next_id_ = 1;
  uint64_t subscription_ = 0;
  std::atomic<uint64_t> forwarded_{0}, unheld_{0}, timed_out_{0}, damaged_{0}, retried_{0};
  std::condition_variable wake_;  // with mutex_: a retry due, or the stop
  bool stopping_ = false;         // guarded by mutex_
  std::thread thread_;
};

}  // namespace vox::cluster
