// The pipeline's checkpoints (with a store): which resident chunks and how many durable
// edits no checkpoint holds yet, when the next checkpoint is due (CheckpointPolicy), and
// the CheckpointWriter that writes it. start() copies nothing: it hands the writer the
// live chunks, all as of the last applied edit, and an edit or undo that changes one of
// them first calls preserve(). When the writer is done, finish() marks the chunks stored
// (they may then be evicted and are read back when needed), or unsaved again after a
// failure: the log still holds every edit, so a failed checkpoint loses nothing.
// Pipeline thread only, but memory_bytes().
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_set>
#include <vector>

#include "server/pipeline/checkpoint_policy.hpp"
#include "server/pipeline/checkpoint_writer.hpp"
#include "server/store/world_store.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/zone.hpp"

namespace vox::pipeline {

struct WorldState;

// A cluster node's checkpoints hold only the zones it may write (docs/CLUSTER.md, "Zone
// checkpoints"): asked at each checkpoint's start.
struct CheckpointScope {
  int zone_chunks = 0;               // the zones' size
  std::vector<world::ZoneId> zones;  // whose chunks this checkpoint writes
  // Of them, those whose every modified chunk it writes, not only those changed since
  // the last checkpoint (a zone taken since: its chunks changed before were not this
  // node's to write).
  std::vector<world::ZoneId> whole;
};

class Checkpoints {
 public:
  using Clock = std::chrono::steady_clock;

  // `own_connection`: `store` is a second connection, written on the writer's thread
  // (`wake` runs there when a checkpoint is done); otherwise the pipeline's own, written
  // on the pipeline thread at start(). `history`: what checkpoints leave of the log.
  // `generator`: the world's, to keep the history's base (CheckpointWriter); null: none.
  Checkpoints(store::WorldStore& store, bool own_connection, CheckpointLimits limits,
              LogRetention history, std::function<void()> wake, Clock::time_point now,
              const world::TerrainGenerator* generator = nullptr,
              std::mutex* history_lock = nullptr);

  // A cluster node: each checkpoint writes only what `scope` (called at its start, with
  // its sequence number) allows; chunks outside it stay unsaved and resident. Set once,
  // before the first checkpoint.
  using Scope = std::function<CheckpointScope(uint64_t seq)>;
  void set_scope(Scope scope) { scope_ = std::move(scope); }

  // An edit changed resident chunk c (its info says unsaved).
  void changed(world::ChunkCoord c) { unsaved_.insert(c); }
  // An undo gave chunk c back its state from before: saved, as it was.
  void saved_again(world::ChunkCoord c) { unsaved_.erase(c); }
  // A cluster node forgot the zone of chunk c, which the checkpoint in flight holds (c
  // went back to the generated terrain): saved, and that checkpoint does not mark it
  // stored.
  void forget(world::ChunkCoord c) {
    unsaved_.erase(c);
    forgotten_.insert(c);
  }
  // Edits made durable (logged) since the last checkpoint started.
  void logged(uint64_t edits) { unsaved_edits_ += edits; }
  // Logged edits no finished checkpoint holds (`in_flight`: of batches being appended):
  // what a restart would replay.
  uint64_t log_tail(uint64_t in_flight) const {
    return checkpoint_edits_ + unsaved_edits_ + in_flight;
  }
  // Whether the log's tail is at its bound: edits are held back (one log line when that
  // starts and one when it ends).
  bool log_full(uint64_t log_tail);
  bool has_unsaved() const { return !unsaved_.empty() || unsaved_edits_ > 0; }
  size_t unsaved_chunks() const { return unsaved_.size(); }
  std::chrono::milliseconds interval() const { return limits_.interval; }

  // The finished checkpoint's result, once (the caller then calls finish()).
  std::optional<CheckpointResult> take_result() { return writer_->take_result(); }
  bool due(Clock::time_point now) const {
    return policy_.due(now, unsaved_.size(), unsaved_edits_);
  }
  // Starts a checkpoint of every unsaved chunk as of edit `seq` (every applied edit, and
  // no other). With the pipeline's own connection it is written before this returns:
  // then its result (the caller finishes it).
  std::optional<CheckpointResult> start(WorldState& state, uint64_t seq, Clock::time_point now);
  // Takes a finished checkpoint's result into the chunks' flags (and logs a failure once).
  void finish(WorldState& state, const CheckpointResult& r, Clock::time_point now);
  // Between batches: takes a finished checkpoint in (finish) and starts one when due.
  // `drain` runs first whenever either happens: it answers every batch in flight and
  // returns the last durable edit's sequence number (a checkpoint holds every applied edit,
  // and a batch undone after a finished one was taken in would put back its chunks'
  // "saved" flags from before: they would never be written). `finished` hears of each
  // checkpoint taken in, at once (before another may start).
  using Finished = std::function<void(const CheckpointResult&)>;
  // `may_start` false: only a finished checkpoint is taken in (a rollback's slices are
  // going in: no checkpoint may cover its record before its last slice).
  void turn(WorldState& state, Clock::time_point now, const std::function<uint64_t()>& drain,
            const Finished& finished, bool may_start = true);
  // At stop, every batch answered (`seq`: the last edit): the checkpoint in flight, then
  // one of everything still unsaved, waited for, so that a restart replays nothing (if the
  // store fails, the log still has every edit).
  void last(WorldState& state, uint64_t seq, const Finished& finished);
  // Before chunk c of the checkpoint in flight changes (an edit, an undo).
  void preserve(world::ChunkCoord c, const world::Chunk& live) { writer_->preserve(c, live); }
  void wait() { writer_->wait(); }  // until the checkpoint in flight is written

  size_t memory_bytes() const { return writer_->memory_bytes(); }  // any thread

 private:
  // The chunks a checkpoint starting now writes (all unsaved ones, without a scope); the
  // others leave unsaved_.
  std::vector<world::ChunkCoord> take_unsaved(WorldState& state, uint64_t seq);

  const CheckpointLimits limits_;
  const bool own_connection_;
  const LogRetention history_;
  Scope scope_;
  CheckpointPolicy policy_;
  std::unique_ptr<CheckpointWriter> writer_;
  // Resident chunks with info.unsaved; edits logged since the last checkpoint started, and
  // those the one in flight holds (back to unsaved when it fails).
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> unsaved_;
  // Chunks forgotten while the checkpoint in flight held them (emptied when it finishes).
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> forgotten_;
  uint64_t unsaved_edits_ = 0, checkpoint_edits_ = 0;
  bool failing_ = false;   // the last checkpoint failed (logged once)
  bool log_full_ = false;  // edits are held back
};

}  // namespace vox::pipeline
