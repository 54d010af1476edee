// The pipeline's side of its checkpoints (the Checkpoints part keeps the rest): when one
// is due it first answers every batch in flight, so that a checkpoint holds every applied
// edit; a finished one goes into the stats and the observer.
#include <spdlog/spdlog.h>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

void WorldPipeline::checkpoint_if_due(Clock::time_point now) {
  if (!checkpoints_) return;
  if (auto r = checkpoints_->take_result()) {
    // Batches in flight first: one undone after a failed checkpoint was taken would put
    // back its chunks' "saved" flags from before, and they would never be written.
    finish_pending(0);
    finish_checkpoint(*r, now);
  }
  if (!checkpoints_->due(now)) return;
  // A checkpoint holds every applied edit: the batches in flight are durable first (or
  // undone).
  finish_pending(0);
  start_checkpoint(now);
}

uint64_t WorldPipeline::logged_since_checkpoint() const {
  return checkpoints_->log_tail(commit_->edits_in_flight());
}

void WorldPipeline::start_checkpoint(Clock::time_point now) {
  // Every applied edit, and no other; written on this thread without a second connection.
  if (auto r = checkpoints_->start(*state_, commit_->last_seq(), now))
    finish_checkpoint(*r, Clock::now());
}

void WorldPipeline::finish_checkpoint(const CheckpointResult& r, Clock::time_point now) {
  checkpoints_->finish(*state_, r, now);
  if (observer_.checkpoint) observer_.checkpoint(r.seconds, r.coords.size(), r.bytes, r.ok);
  std::lock_guard lock(stats_mutex_);
  stats_.stored_chunks = state_->stored.size();
  stats_.unsaved_chunks = checkpoints_->unsaved_chunks();
  stats_.checkpoints += r.ok ? 1 : 0;
  stats_.checkpoint_failures += r.ok ? 0 : 1;
  if (r.ok) stats_.checkpoint_seq = r.seq;
}

// At stop: the checkpoint in flight, then one of everything still unsaved, so that a
// restart replays nothing (if the store fails, the log still has every edit).
void WorldPipeline::final_checkpoint() {
  if (!checkpoints_) return;
  checkpoints_->wait();
  if (auto r = checkpoints_->take_result()) finish_checkpoint(*r, Clock::now());
  if (!checkpoints_->has_unsaved()) return;
  const size_t chunks = checkpoints_->unsaved_chunks();
  start_checkpoint(Clock::now());
  checkpoints_->wait();
  if (auto r = checkpoints_->take_result()) finish_checkpoint(*r, Clock::now());
  if (!checkpoints_->has_unsaved())
    spdlog::info("checkpoint at shutdown: {} chunks through edit {}", chunks, commit_->last_seq());
}

}  // namespace vox::pipeline
