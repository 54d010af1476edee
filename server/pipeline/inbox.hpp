// The pipeline's front door: the one state other threads share with the pipeline thread.
// Edits, region changes and inspections (in arrival order) and load requests go to the
// BatchScheduler; views set or dropped and level-of-detail wants wait here until the
// pipeline takes them between batches; the background threads' signals (an append
// landed, terrain generated, a checkpoint written) and stop() wake it.
//
// Every member takes the inbox's mutex. The pipeline thread reads and takes what it needs
// through locked() and waits through wait_unless() / wait_until(); the functions it passes
// run under the lock, so they may read pipeline-thread state but must not block or take
// the pipeline's other locks. Lock order: this mutex, then the leaf locks taken under
// it (the prefetcher's and the checkpoint writer's, through the accounted bytes that
// batch_ready and the scheduler's cost callback read); never the other way round.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <unordered_map>
#include <utility>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/lod_mesh_store.hpp"
#include "server/world/chunk_coord.hpp"

namespace vox::pipeline {

class Inbox {
 public:
  using Clock = std::chrono::steady_clock;

  // What the mutex guards.
  struct State {
    explicit State(BatchScheduler s) : scheduler(std::move(s)) {}
    BatchScheduler scheduler;
    bool stopping = false;
    bool append_landed = false;    // a pending batch may be answered
    bool generated_ready = false;  // terrain generated in the background waits
    // Views set or dropped since the pipeline last took them (radius -1: dropped).
    std::unordered_map<LoadOwner, std::pair<world::ChunkCoord, int>> view_updates;
    // Level-of-detail wants set or dropped since (empty: dropped).
    std::unordered_map<LoadOwner, std::vector<LodKey>> lod_updates;
    uint64_t next_anonymous_owner = 1;
  };

  explicit Inbox(BatchScheduler scheduler) : state_(std::move(scheduler)) {}

  // Any thread. Queues the task; false once stopping (the task is left to the caller).
  bool add(OrderedTask& task);
  // Any thread. A one-off load of `chunks` (nearest first) by an owner of its own; `done`
  // is moved in unless stopping (then false).
  bool add_load(std::vector<world::ChunkCoord> chunks, std::function<void()>& done);
  // Any thread. `owner`'s view becomes the ball around `center` whose missing chunks are
  // `chunks`; returns the callback of the request it replaced (to run outside the lock).
  // Nothing once stopping.
  std::function<void()> set_view(LoadOwner owner, world::ChunkCoord center, int radius,
                                 std::vector<world::ChunkCoord> chunks, uint64_t budget_group);
  // Any thread: the owner's loads, view and level-of-detail wants go; returns the dropped
  // request's callback.
  std::function<void()> drop_view(LoadOwner owner);
  void set_lod_view(LoadOwner owner, std::vector<LodKey> keys);  // any thread
  // Any thread: wake-ups of the background threads.
  void append_landed();
  void generated_ready();
  void poke();  // something the pipeline looks at between batches changed
  void stop();  // any thread: from now on nothing is queued

  struct Counts {
    size_t edits = 0, load_chunks = 0, load_owners = 0;
  };
  Counts counts() const;  // any thread

  // Pipeline thread: fn(state) under the lock.
  template <class Fn>
  decltype(auto) locked(Fn&& fn) {
    std::lock_guard lock(mutex_);
    return fn(state_);
  }
  // Pipeline thread: true at once when ready(state); else waits for a wake-up or
  // wait(state) (a duration) and returns false. Both run under the lock, so no wake-up
  // between the look and the wait is lost.
  template <class Ready, class Wait>
  bool wait_unless(Ready&& ready, Wait&& wait) {
    std::unique_lock lock(mutex_);
    if (ready(state_)) return true;
    cv_.wait_for(lock, wait(state_));
    return false;
  }
  // Pipeline thread: waits until done(state) (under the lock) or `until`.
  template <class Done>
  void wait_until(Clock::time_point until, Done&& done) {
    std::unique_lock lock(mutex_);
    cv_.wait_until(lock, until, [&] { return done(state_); });
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  State state_;
};

// A task the stopped pipeline will not run, answered on the caller's thread: an edit or a
// region change refused (shutting down), an inspection run with `cancelled`.
void refuse_stopped(OrderedTask& task, bool cancelled);

}  // namespace vox::pipeline
