// Group commit, pipelined: each batch's accepted edits get their sequence numbers here and
// are appended to the store on the StoreAppender's thread while the pipeline goes on with
// the next batches; a batch is answered (its meshes published, its results sent) only
// once its append is durable, in batch order. An append that fails undoes its batch and
// every later one (they were applied on top of it), newest first: those in its
// transaction failed with it, the later ones are not tried. The store then rests for
// `retry` (edits are refused untried), and the next append forgets the failed appends'
// edits, which may have landed all the same. Pipeline thread only.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/store_appender.hpp"
#include "server/store/world_store.hpp"

namespace vox::pipeline {

class DurableCommit {
 public:
  // What the pipeline does with a batch: answer it (durable: publish and accept; else
  // refuse what it accepted), undo it (after a failed append, newest first, before any
  // is answered), and note an append's figures (`waited`: seconds it stood waiting).
  struct Hooks {
    std::function<void(EditBatch&, bool durable)> answer;
    std::function<void(EditBatch&)> undo;
    std::function<void(const AppendOutcome&, double waited)> committed;
  };

  // `landed` runs on the appender's thread when an append lands (it wakes the pipeline).
  // `store` must outlive this.
  DurableCommit(store::WorldStore& store, std::chrono::milliseconds retry,
                std::function<void()> landed, Hooks hooks);
  ~DurableCommit();  // every batch was answered; joins the appender

  // The world as restored: the next edit's sequence number.
  void restore(uint64_t next_seq) { next_seq_ = next_seq; }
  uint64_t last_seq() const { return next_seq_ - 1; }
  // After a failed append the store rests: edits are refused untried until retry_at().
  bool resting(Clock::time_point now) const { return now < retry_at_; }
  Clock::time_point retry_at() const { return retry_at_; }

  // Appends b's accepted edits (numbered here, never reused) and `regions` after the
  // newest append in flight; then add() hands the batch over until it is answered.
  void start(EditBatch& b, std::optional<store::RegionWrite> regions);
  void add(EditBatch b) { pending_.push_back(std::move(b)); }

  bool empty() const { return pending_.empty(); }
  size_t size() const { return pending_.size(); }
  uint64_t edits_in_flight() const;
  // Whether the oldest batch's append is in (or it has none).
  bool oldest_landed() const;
  // Answers the batches whose appends have landed, oldest first; past `keep` batches in
  // flight, waits for the oldest (0: every batch is answered when this returns).
  void finish(size_t keep);
  // Adds the seconds the pipeline stood waiting for the oldest append.
  void waited_for_oldest(double seconds) { pending_.front().waited += seconds; }

  // The newest mesh a pending batch made of `c` (null: none made one).
  MeshVersionPtr newest_mesh(world::ChunkCoord c) const;
  // The chunks whose samples pending batches changed (may repeat).
  std::vector<world::ChunkCoord> pending_chunks() const;
  // Whether a pending batch changed samples that meshes of `chunks` read.
  bool near_pending_edits(const std::vector<world::ChunkCoord>& chunks) const;
  // Until no append is running (reads share the store's connection with them).
  void wait_for_appends() const;

 private:
  void fail(const std::string& error, bool fenced);

  const std::chrono::milliseconds retry_;
  const Hooks hooks_;
  std::deque<EditBatch> pending_;  // oldest first
  uint64_t next_seq_ = 1;
  Clock::time_point retry_at_{};
  // Sequence numbers of failed appends since the last that worked.
  std::optional<store::WorldStore::SeqRange> doubtful_;
  bool failing_ = false;  // the last append failed (logged once)
  std::unique_ptr<StoreAppender> appender_;
};

}  // namespace vox::pipeline
