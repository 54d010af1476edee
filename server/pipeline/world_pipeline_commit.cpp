// Group commit, pipelined: each batch's accepted edits are appended to the store on the
// StoreAppender's thread while the pipeline goes on with the next batches and load passes; a batch
// is answered (meshes published, results sent) only once its append is durable, in batch order. An
// append that fails undoes its batch and every later one (they were applied on top of it): those in
// its transaction failed with it, the later ones are not tried.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

template <typename Future>
bool landed(const Future& f) {  // no append, or its outcome is in
  return !f.valid() || f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
}

}  // namespace

void WorldPipeline::start_append(Batch& b) {
  const int64_t unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count();
  std::vector<store::LoggedEdit> log;
  log.reserve(b.accepted.size());
  // Sequence numbers are never reused, even after a failed append (its outcome may be in
  // doubt): the log may have gaps, never two edits with one number.
  for (size_t i = 0; i < b.accepted.size(); ++i) {
    const EditTask& t = *b.accepted[i];
    log.push_back({next_seq_++, unix_ms, t.author, t.edit, b.keep[i]});
  }
  if (!log.empty()) b.seqs = {log.front().seq, log.back().seq};  // else {0, 0}: regions only
  std::optional<store::RegionWrite> regions = regions_.write_for_append(b.regions);
  b.appended_at = Clock::now();
  // Appends that failed since the last that worked may have landed all the same: their
  // edits were undone here, so they go from the log with this append.
  std::vector<store::WorldStore::SeqRange> forget;
  if (doubtful_) forget.push_back(*doubtful_);
  std::shared_future<AppendOutcome> before;  // the newest append in flight
  for (auto it = pending_.rbegin(); it != pending_.rend() && !before.valid(); ++it)
    before = it->outcome;
  b.outcome =
      appender_->append(std::move(log), std::move(forget), std::move(before), std::move(regions));
}

void WorldPipeline::repair_regions(Clock::time_point now, bool now_anyway) {
  if (!regions_.doubtful() || !appender_ || !pending_.empty()) return;
  if (!now_anyway && now < store_retry_at_) return;
  Batch b;  // no tasks: the append carries the region table (and forgets doubtful edits)
  start_append(b);
  pending_.push_back(std::move(b));
}

void WorldPipeline::wait_for_answer(PipelineStats& batch, Clock::time_point until) {
  // Each pending batch is answered as soon as its append lands (oldest first), not when
  // the newest's does.
  while (!pending_.empty()) {
    Batch& oldest = pending_.front();
    const Clock::time_point start = Clock::now();
    bool go_on = false;  // an edit arrived, or the pipeline stops
    {
      std::unique_lock lock(queue_mutex_);
      queue_cv_.wait_until(lock, until, [&] {
        go_on = stopping_ || scheduler_.has_ordered();
        return go_on || landed(oldest.outcome);
      });
    }
    oldest.waited += seconds_since(start);
    if (!landed(oldest.outcome)) break;  // the wait is over, or an edit arrived
    finish_pending(batch, SIZE_MAX);     // every batch whose append has landed
    if (go_on) break;
  }
  finish_pending(batch, kMaxPendingBatches);
}

void WorldPipeline::finish_pending(PipelineStats& batch, size_t keep) {
  while (!pending_.empty()) {
    Batch& b = pending_.front();
    const Clock::time_point start = Clock::now();
    const bool ready = landed(b.outcome);
    if (!ready && pending_.size() <= keep) return;
    if (b.outcome.valid()) {
      const AppendOutcome& out = b.outcome.get();
      b.waited += ready ? 0 : seconds_since(start);
      if (observer_.commit && out.first)
        observer_.commit(out.seconds, out.edits, out.error.empty());
      if (observer_.commit_wait) observer_.commit_wait(b.waited);
      if (!out.error.empty()) return fail_pending(batch, out.error);
      doubtful_.reset();
      if (store_failing_) {
        store_failing_ = false;
        spdlog::info("world store: writing again; edits are accepted");
      }
    }
    answer(b, true, batch);
    pending_.pop_front();
  }
}

// The oldest pending append failed: every pending batch is undone (newest first) and its
// accepted edits refused; nothing of them was published.
void WorldPipeline::fail_pending(PipelineStats& batch, const std::string& error) {
  for (Batch& b : pending_) {
    if (b.outcome.valid()) b.outcome.wait();  // the later ones return without trying
  }
  for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) {
    roll_back(it->undo);
    regions_.undo(it->regions);
  }
  // No append works in between, so one range covers every doubtful one (the later
  // batches' were not tried; forgetting them too is harmless).
  for (const Batch& b : pending_) {
    if (!b.outcome.valid() || b.seqs.first == 0) continue;  // not tried, or regions only
    if (!doubtful_) doubtful_ = b.seqs;
    doubtful_->last = b.seqs.last;
  }
  store_retry_at_ = Clock::now() + config_.store_retry;
  if (!store_failing_) spdlog::error("world store: {}; edits are refused until it works", error);
  store_failing_ = true;
  for (Batch& b : pending_) answer(b, false, batch);
  pending_.clear();
}

MeshVersionPtr WorldPipeline::newest_mesh(ChunkCoord c) const {
  for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) {
    const auto& dirty = it->dirty;
    const auto at = std::lower_bound(dirty.begin(), dirty.end(), c);
    if (at != dirty.end() && *at == c && it->fresh[at - dirty.begin()])
      return it->fresh[at - dirty.begin()];
  }
  return meshes_.get(c);
}

bool WorldPipeline::near_pending_edits(const std::vector<ChunkCoord>& chunks) const {
  if (pending_.empty() || chunks.empty()) return false;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> touched;
  for (const Batch& b : pending_)
    for (const Undo::Patch& p : b.undo.patches) touched.insert(p.coord);
  for (const ChunkCoord& c : chunks)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (touched.count(c.offset(dx, dy, dz))) return true;
  return false;
}

void WorldPipeline::wait_for_appends() const {
  for (const Batch& b : pending_) {
    if (b.outcome.valid()) b.outcome.wait();
  }
}

}  // namespace vox::pipeline
