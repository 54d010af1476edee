// Writes the pipeline's checkpoints: the chunks edits changed since the last one, all as
// of one sequence number, compressed and written to the store (which makes them visible
// at once, records that sequence and trims the log through it). In the background (its
// own thread and its own store connection: the pipeline keeps applying and appending
// edits meanwhile) or, given the pipeline's own connection, on the caller's thread.
//
// Copy on write: a job names the live chunks. The writer encodes each from the pipeline's
// own chunk, unless the pipeline is about to change it first: the pipeline then calls
// preserve(), which keeps a copy of the chunk as it was (waiting, if the writer is
// encoding that very chunk, until it is done). So a checkpoint costs the pipeline nothing
// but the copies of the chunks it changes again before the writer reached them.
//
// Bounded: one job at a time (the pipeline submits the next once it took the result of
// the last); memory_bytes() counts its records and copies for the memory budget.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "server/store/chunk_codec.hpp"
#include "server/store/world_store.hpp"
#include "server/world/chunk.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct CheckpointJob {
  uint64_t seq = 0;     // the chunks include every edit through this one, and no later one
  store::LogTrim trim;  // what the log loses
  // The pipeline's chunks: never evicted, never replaced, and changed only after
  // preserve(), until the result is taken.
  std::vector<std::pair<world::ChunkCoord, const world::Chunk*>> chunks;
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
  // Otherwise submit() writes on the caller's thread. With `history` (the world's
  // generator; null for a cluster's zones), a job whose trim keeps a window moves the
  // history's base instead (store::advance_history) after writing.
  // `history_lock`: held by a rollback while it reads the history; tried, never waited for.
  CheckpointWriter(store::WorldStore& store, bool background, std::function<void()> on_done,
                   const world::TerrainGenerator* history = nullptr,
                   std::mutex* history_lock = nullptr);
  ~CheckpointWriter();  // finishes the job in flight and joins
  CheckpointWriter(const CheckpointWriter&) = delete;
  CheckpointWriter& operator=(const CheckpointWriter&) = delete;

  // Pipeline thread, nothing in flight (take_result() returned the last job's result).
  void submit(CheckpointJob job);
  // Pipeline thread, before it changes chunk `c` of the job in flight (`live` is that
  // chunk): keeps a copy of it for the writer unless the writer is done with it.
  void preserve(world::ChunkCoord c, const world::Chunk& live);
  // Pipeline thread: the finished job's result, once.
  std::optional<CheckpointResult> take_result();
  // Pipeline thread: waits until the job in flight has finished.
  void wait();
  size_t memory_bytes() const;  // any thread: the job's records and copies

 private:
  void work();
  CheckpointResult run(const CheckpointJob& job);  // encodes and writes
  void keep_history(const CheckpointJob& job);     // after a job written: the base moves
  void done(CheckpointResult r);                   // publishes the result; the job is over

  store::WorldStore& store_;
  const std::function<void()> on_done_;
  const world::TerrainGenerator* const history_;
  std::mutex* const history_lock_;
  store::ChunkEncoder encoder_;  // the writing thread's
  mutable std::mutex mutex_;     // leaf lock; never held while encoding or writing
  std::condition_variable cv_;
  std::optional<CheckpointJob> job_;
  std::optional<CheckpointResult> result_;
  // The job in flight's chunks not encoded yet; the copies preserve() made of some; the
  // one being encoded from the pipeline's chunk.
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> pending_;
  std::unordered_map<world::ChunkCoord, world::Chunk, world::ChunkCoordHash> preserved_;
  std::optional<world::ChunkCoord> reading_;
  size_t bytes_ = 0;   // records encoded and copies held
  bool busy_ = false;  // a job submitted and its result not produced yet
  std::chrono::steady_clock::time_point last_history_warning_{};  // the writing thread's
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace vox::pipeline
