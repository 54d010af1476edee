// Online rollbacks (docs/OPERATIONS.md, "Rolling back"; issue 43): an admin's request to
// undo what edits matching a query did, while players go on editing. One at a time, on a
// thread of their own ("vox-rollback") with a store connection of their own:
//   1. plan: the chunks the rollback recomputes (store::prepare_rollback, a dry run);
//   2. freeze them in the pipeline (RollbackTask): edits reaching them are refused
//      SERVER_BUSY from then on, so nothing after the freeze changes what is recomputed;
//   3. recompute them from the history as of the last edit before the freeze, once the
//      store holds it; if the recomputed set grew meanwhile, freeze the rest and again;
//   4. put them in place in slices of kSlice chunks, each an ordered task re-meshed and
//      published like an edit's batch; the first slice's batch logs the rollback record
//      (durable before anything of it is published), the frozen chunks thaw as their
//      slice lands.
// The pipeline thread only applies; the recomputation costs this thread, not the players'
// edits. Bounded: a queue of kMaxQueued requests; at most max_chunks chunks held.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "server/store/world_history.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

class WorldPipeline;

struct RollbackReport {
  enum class Status { kOk, kRefused, kTooMany, kUnavailable, kBusy, kStopped };
  Status status = Status::kOk;
  std::string message;  // why, unless kOk
  uint64_t record = 0;  // the logged record's sequence number (0: a dry run, or nothing to do)
  size_t edits = 0;     // edits whose place in the world changed (or would)
  size_t chunks = 0;    // chunks recomputed (or that would be)
  uint64_t history_from = 0;  // the oldest edit the history holds, and when
  int64_t history_from_ms = 0;
  double seconds = 0;
};

class Rollbacks {
 public:
  struct Job {
    store::RollbackQuery query;
    bool dry_run = false;
    std::string by;  // the admin's player id: the record's author
    // On the rollback thread (or the caller's, refused at once); must not block.
    std::function<void(const RollbackReport&)> done;
  };
  static constexpr size_t kMaxQueued = 4;
  static constexpr size_t kSlice = 16;  // chunks per install batch (~5 ms of meshing)

  // `store`: a connection no one else uses; `pipeline`, `store` and `history_lock` (the
  // checkpoint writer tries it before it moves the history's base) outlive this.
  // `keeps_history`: checkpoints keep a window (or everything); else every rollback is
  // refused.
  Rollbacks(WorldPipeline& pipeline, store::WorldStore& store,
            const world::TerrainGenerator& generator, size_t max_chunks, std::mutex& history_lock,
            bool keeps_history);
  ~Rollbacks();  // stop()
  Rollbacks(const Rollbacks&) = delete;
  Rollbacks& operator=(const Rollbacks&) = delete;

  // Any thread: queued, or answered kBusy (queue full) / kStopped at once.
  void submit(Job job);
  // Any thread, before the pipeline stops: the queued jobs are answered kStopped; the
  // running one ends before its record is logged, or, once it is, puts its slices in
  // place first (a few seconds at most; if the store fails, the pipeline writes no
  // checkpoint past the record, and the next start replays it); the thread is joined.
  // Idempotent.
  void stop();

 private:
  void work();
  RollbackReport run(const Job& job);
  // Via the pipeline, waiting: chunks frozen, the last edit before; chunks thawed; a slice
  // put in place (its record's seq when it carried one, 0 if not; nullopt: undone).
  std::optional<uint64_t> freeze(std::vector<world::ChunkCoord> coords);  // nullopt: refused
  bool stopping();
  void thaw(std::vector<world::ChunkCoord> coords);
  std::optional<uint64_t> install(std::vector<std::pair<world::ChunkCoord, world::Chunk>> chunks,
                                  const std::vector<uint64_t>* undoes, const std::string& by,
                                  bool last);
  bool wait_durable(uint64_t through);  // until the store holds every edit through it

  WorldPipeline& pipeline_;
  store::WorldStore& store_;                  // the rollback thread's
  const world::TerrainGenerator& generator_;  // the pipeline's (const: any thread)
  const size_t max_chunks_;
  std::mutex& history_lock_;
  const bool keeps_history_;
  std::mutex mutex_;  // leaf lock: the queue and stopping_
  std::condition_variable cv_;
  std::deque<Job> queue_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace vox::pipeline
