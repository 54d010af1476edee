// The pipeline's checkpoints (with a store): between batches, when CheckpointPolicy says
// so, the chunks changed since the last checkpoint are copied, all as of the last applied
// edit, and handed to the CheckpointWriter; when it has written them (and trimmed the log
// through that edit) they may be evicted and are read back from the store when needed.
// A failed checkpoint loses nothing: the log still holds every edit, and the chunks stay
// unsaved (resident) for the next try.
#include <spdlog/spdlog.h>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

void WorldPipeline::checkpoint_if_due(Clock::time_point now) {
  if (!checkpointer_) return;
  PipelineStats counts;
  if (auto r = checkpointer_->take_result()) {
    // Batches in flight first: one undone after a failed checkpoint was taken would put
    // back its chunks' "saved" flags from before, and they would never be written.
    finish_pending(counts, 0);
    finish_checkpoint(*r, now);
  }
  if (!checkpoint_policy_->due(now, unsaved_.size(), unsaved_edits_)) return;
  // A checkpoint holds every applied edit: the batches in flight are durable first (or
  // undone).
  finish_pending(counts, 0);
  start_checkpoint(now);
}

uint64_t WorldPipeline::logged_since_checkpoint() const {
  uint64_t tail = checkpoint_edits_ + unsaved_edits_;
  for (const Batch& b : pending_) tail += b.accepted.size();
  return tail;
}

bool WorldPipeline::log_full(uint64_t log_tail) {
  const bool full = checkpoint_policy_->log_full(log_tail);
  if (full && !log_full_) {
    spdlog::warn(
        "world store: {} edits in the log await a checkpoint; edits are refused "
        "(SERVER_BUSY) until it is written",
        log_tail);
  } else if (!full && log_full_) {
    spdlog::info("world store: a checkpoint trimmed the log; edits are taken again");
  }
  log_full_ = full;
  return full;
}

void WorldPipeline::start_checkpoint(Clock::time_point now) {
  WorldState& st = *state_;
  const uint64_t seq = next_seq_ - 1;  // every applied edit, and no other
  CheckpointJob job{.seq = seq, .trim_through = config_.keep_log ? 0 : seq};
  const std::vector<ChunkCoord> coords(unsaved_.begin(), unsaved_.end());
  for (const ChunkCoord& c : coords) {
    WorldState::ChunkInfo& info = st.info.at(c);  // unsaved chunks are never evicted
    info.unsaved = false;
    info.checkpointing = true;
  }
  unsaved_.clear();
  // The writer reads the chunks themselves; a batch that changes one first preserves it
  // (apply_edit_task, roll_back), so the checkpoint has every chunk as of `seq`.
  job.chunks.reserve(coords.size());
  for (const ChunkCoord& c : coords) job.chunks.emplace_back(c, st.chunks.find(c));
  checkpoint_edits_ = std::exchange(unsaved_edits_, 0);
  checkpoint_policy_->started(now);
  checkpointer_->submit(std::move(job));
  // Written on this thread (no second connection): its result is ready now.
  if (!config_.checkpoint_store) finish_checkpoint(*checkpointer_->take_result(), Clock::now());
}

void WorldPipeline::finish_checkpoint(const CheckpointResult& r, Clock::time_point now) {
  WorldState& st = *state_;
  checkpoint_policy_->finished(now, r.ok);
  for (const ChunkCoord& c : r.coords) {
    auto it = st.info.find(c);
    if (it == st.info.end()) continue;  // cannot happen: not evictable while written
    it->second.checkpointing = false;
    if (r.ok) {
      st.stored.insert(c);
    } else if (!it->second.unsaved) {
      it->second.unsaved = true;
      unsaved_.insert(c);
    }
  }
  if (!r.ok) unsaved_edits_ += checkpoint_edits_;
  checkpoint_edits_ = 0;
  if (observer_.checkpoint) observer_.checkpoint(r.seconds, r.coords.size(), r.bytes, r.ok);
  if (r.ok) {
    spdlog::debug("checkpoint: {} chunks through edit {} ({} KiB) in {:.0f} ms", r.coords.size(),
                  r.seq, r.bytes >> 10, r.seconds * 1000);
    if (checkpoint_failing_) spdlog::info("checkpoint: writing again (through edit {})", r.seq);
  } else if (!checkpoint_failing_) {
    spdlog::error("checkpoint: {}; its chunks stay in memory, the log keeps their edits", r.error);
  }
  checkpoint_failing_ = !r.ok;
  std::lock_guard lock(stats_mutex_);
  stats_.stored_chunks = st.stored.size();
  stats_.unsaved_chunks = unsaved_.size();
  stats_.checkpoints += r.ok ? 1 : 0;
  stats_.checkpoint_failures += r.ok ? 0 : 1;
  if (r.ok) stats_.checkpoint_seq = r.seq;
}

// At stop: the checkpoint in flight, then one of everything still unsaved, so that a
// restart replays nothing (if the store fails, the log still has every edit).
void WorldPipeline::final_checkpoint() {
  if (!checkpointer_) return;
  checkpointer_->wait();
  if (auto r = checkpointer_->take_result()) finish_checkpoint(*r, Clock::now());
  if (unsaved_.empty() && unsaved_edits_ == 0) return;
  const size_t chunks = unsaved_.size();
  start_checkpoint(Clock::now());
  checkpointer_->wait();
  if (auto r = checkpointer_->take_result()) finish_checkpoint(*r, Clock::now());
  if (unsaved_.empty() && unsaved_edits_ == 0) {
    spdlog::info("checkpoint at shutdown: {} chunks through edit {}", chunks, next_seq_ - 1);
  }
}

}  // namespace vox::pipeline
