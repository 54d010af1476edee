// The pipeline's figures (PipelineStats): written on the pipeline thread as batches go,
// read by any thread; and the counts of the batch in hand, for the slow-batch log.
#pragma once

#include <mutex>

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/pipeline_config.hpp"

namespace vox::pipeline {

struct WorldState;

class StatsBook {
 public:
  // Pipeline thread: adds `delta` to the totals and to the batch in hand's counts, with the
  // world's residency as it is now (`unsaved_chunks`: the checkpoints').
  void count(const BatchCounts& delta, const WorldState& state, size_t unsaved_chunks);
  // Pipeline thread: changes the figures under the lock.
  template <class Fn>
  void update(Fn&& fn) {
    std::lock_guard lock(mutex_);
    fn(stats_);
  }
  // The world's residency figures (loaded, modified, their bytes, stored) into `s`.
  static void residency(PipelineStats& s, const WorldState& state);
  void start_batch() { batch_ = {}; }                  // pipeline thread
  const BatchCounts& batch() const { return batch_; }  // pipeline thread
  // One line for a slow batch (`took` seconds, `loaded` chunks): every edit behind it waited.
  void log_slow(double took, size_t loaded) const;  // pipeline thread
  PipelineStats snapshot() const {                  // any thread
    std::lock_guard lock(mutex_);
    return stats_;
  }

 private:
  mutable std::mutex mutex_;  // leaf lock
  PipelineStats stats_;
  BatchCounts batch_;
};

}  // namespace vox::pipeline
