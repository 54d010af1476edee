// Appends the pipeline's batches of accepted edits to the world store on one long-lived
// thread, in the order they are given, while the pipeline goes on. One thread that sleeps
// between appends: the kernel wakes a sleeper ahead of busy threads, whereas a thread
// started per append waited for a core up to 25 ms (p99) with 500 players on two cores.
//
// Group commit across batches: the appends queued while one is being made durable go to the
// store together, in one transaction (one fsync), so a slow fsync holds up the batches
// behind it once, not once each. An append carrying protected regions goes alone.
//
// Bounded by its owner: the pipeline has at most a few batches in flight and waits for
// the oldest past that (WorldPipeline::kMaxPendingBatches).
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "server/store/world_store.hpp"

namespace vox::pipeline {

struct AppendOutcome {
  std::string error;  // empty: durable
  // The error was a cluster zone's fence (store::FencedError: another node writes the zone
  // now): it says nothing about the store, which does not rest.
  bool fenced = false;
  double seconds = 0;  // the store's transaction (0 when not tried)
  // The transaction may carry several appends: the edits in it, and whether this append
  // was its first (a transaction's figures are counted once).
  size_t edits = 0;
  bool first = true;
};

class StoreAppender {
 public:
  // `store` is used from the appender's thread only while an append runs; `landed` runs
  // there after each transaction's outcomes are set (no lock of ours held; must not block).
  StoreAppender(store::WorldStore& store, std::function<void()> landed);
  ~StoreAppender();  // runs the appends queued, then joins
  StoreAppender(const StoreAppender&) = delete;
  StoreAppender& operator=(const StoreAppender&) = delete;

  // Pipeline thread. Appends `log` (and forgets `forget`, and with `regions` makes them
  // the stored protected regions) after every earlier append. `before` is the outcome of
  // the append given just before this one, or invalid when none is in flight: if it
  // failed, this one is not tried and fails too. (Appends grouped in one transaction share
  // its outcome: only the group's first `before` can have landed, and it alone is checked.)
  std::shared_future<AppendOutcome> append(
      std::vector<store::LoggedEdit> log, std::vector<store::WorldStore::SeqRange> forget,
      std::shared_future<AppendOutcome> before,
      std::optional<store::RegionWrite> regions = std::nullopt);

 private:
  struct Job {
    std::vector<store::LoggedEdit> log;
    std::vector<store::WorldStore::SeqRange> forget;
    std::optional<store::RegionWrite> regions;
    std::shared_future<AppendOutcome> before;
    std::promise<AppendOutcome> promise;
  };
  // The most appends one transaction carries: a guard (the pipeline keeps at most four in
  // flight, so a group holds at most three).
  static constexpr size_t kMaxGroup = 16;
  void work();
  // Under mutex_: the queued appends the next transaction carries (at least one).
  std::vector<Job> take_group();
  void run(std::vector<Job>& group);  // sets each job's outcome

  store::WorldStore& store_;
  const std::function<void()> landed_;
  std::mutex mutex_;  // leaf lock; never held while appending
  std::condition_variable cv_;
  std::deque<Job> jobs_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace vox::pipeline
