// Writes the pipeline's checkpoints: the chunks edits changed since the last one, all as
// of one sequence number (encoded by the pipeline), to the store in one transaction that
// also records that sequence and trims the log through it. In the
// background (its own thread and its own store connection: the pipeline keeps appending
// edits meanwhile) or, given the pipeline's own connection, on the caller's thread.
//
// Bounded: one job at a time (the pipeline submits the next once it took the result of
// the last), and memory_bytes() counts its records for the memory budget.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "server/store/world_store.hpp"

namespace vox::pipeline {

struct CheckpointJob {
  uint64_t seq = 0;           // the chunks include every edit through this one, and no later one
  uint64_t trim_through = 0;  // the log is deleted through this edit (0: kept)
  std::vector<store::ChunkRecord> records;  // encoded, each with `seq`
};

struct CheckpointResult {
  uint64_t seq = 0;
  std::vector<world::ChunkCoord> coords;  // the job's chunks: stored now, unless !ok
  bool ok = false;
  std::string error;  // the store's, when !ok
  size_t bytes = 0;   // the chunk records written
  double seconds = 0;
};

class CheckpointWriter {
 public:
  // `background`: a thread writes to `store`, a connection no one else uses while this
  // lives; `on_done` then runs on it after each job (no lock held; must not block).
  // Otherwise submit() writes on the caller's thread.
  CheckpointWriter(store::WorldStore& store, bool background, std::function<void()> on_done);
  ~CheckpointWriter();  // finishes the job in flight and joins
  CheckpointWriter(const CheckpointWriter&) = delete;
  CheckpointWriter& operator=(const CheckpointWriter&) = delete;

  // Pipeline thread, nothing in flight (take_result() returned the last job's result).
  void submit(CheckpointJob job);
  // Pipeline thread: the finished job's result, once.
  std::optional<CheckpointResult> take_result();
  // Pipeline thread: waits until the job in flight has finished.
  void wait();
  size_t memory_bytes() const;  // any thread: the records of the job in flight

  // The work itself: one transaction.
  static CheckpointResult write(store::WorldStore& store, const CheckpointJob& job);

 private:
  void work();

  store::WorldStore& store_;
  const std::function<void()> on_done_;
  mutable std::mutex mutex_;  // leaf lock; never held while writing
  std::condition_variable cv_;
  std::optional<CheckpointJob> job_;
  std::optional<CheckpointResult> result_;
  size_t job_bytes_ = 0;
  bool busy_ = false;  // a job submitted and its result not produced yet
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace vox::pipeline
