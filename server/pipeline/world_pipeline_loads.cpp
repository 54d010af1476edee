// The world pipeline's load pass and its memory management: what a batch does besides
// its edits. Pipeline thread (see world_pipeline.hpp).
#include <spdlog/spdlog.h>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

// With the terrain and the meshes on their way at their worst case, so that load passes
// taken while earlier ones wait for terrain do not overrun the memory budget.
size_t WorldPipeline::accounted_bytes() const {
  return resident_bytes() + loads_->memory_bytes() +
         (checkpoints_ ? checkpoints_->memory_bytes() : 0);
}

size_t WorldPipeline::resident_bytes() const {
  return state_->chunks.memory_bytes() + meshes_.memory_bytes() + lod_->memory_bytes() +
         other_bytes_.load(std::memory_order_relaxed);
}

size_t WorldPipeline::load_work_allowed(bool edits_waiting) {
  const size_t full =
      edits_waiting ? config_.load_pass_work_while_edits_wait : config_.load_pass_work;
  return budget_.load_work(accounted_bytes(), full);
}

void WorldPipeline::take_view_updates() {
  if (view_updates_.empty()) return;
  for (const auto& [owner, view] : view_updates_) state_->views.set(owner, view.first, view.second);
  view_updates_.clear();
  loads_->drop_unviewed();
}

// The batch's load pass, planned on the world as its edits left it. Pipeline thread; the
// scheduler is read under the queue lock, and its cost callback touches only
// pipeline-thread state.
std::vector<LoadSlice> WorldPipeline::take_loads(LoadPlan& plan, Clock::time_point now) {
  std::lock_guard lock(queue_mutex_);
  // The views whose requests this pass takes must be the ones eviction protects: a view
  // set after the batch started would otherwise have its meshed chunks passed over here
  // (nothing to load) yet evicted below, and the session would wait for them forever.
  take_view_updates();
  if (!scheduler_.has_loads()) return {};
  return scheduler_.take_loads(
      // Edits waiting to apply, or applied and waiting for the store to be answered: a
      // short pass, so that they are not held up behind it.
      load_work_allowed(scheduler_.has_ordered() || batches_in_flight()),
      [&](ChunkCoord c) { return loads_->cost(c, plan, now); }, config_.load_scan_limit, now);
}

// One load pass: installs the terrain generated in the background, queues what the
// planned chunks still miss, meshes and publishes every waiting chunk whose neighbourhood
// is complete, then runs the finished requests' callbacks.
void WorldPipeline::process_loads(std::vector<LoadSlice>& loads, LoadPlan& plan,
                                  Clock::time_point now) {
  BatchCounts delta;
  loads_->wait_for(loads, plan);
  // After the new waiting chunks pinned their neighbourhoods: terrain ready for them is kept.
  delta.chunks_generated += loads_->install_generated(now);
  std::vector<ChunkCoord> published;
  if (loads_->waiting()) {
    std::vector<ChunkCoord> dirty = loads_->take_meshable(now, delta);
    finish_landed();  // not held up by the meshing
    // A mesh never shows an edit that is not durable: those batches are answered first.
    if (commit_ && commit_->near_pending_edits(dirty)) finish_pending(0);
    published = remesh_and_publish(dirty);
    delta.meshes_published += published.size();
  }
  count(delta);
  {
    std::lock_guard lock(stats_mutex_);
    stats_.chunks_generating = loads_->generating();
    stats_.meshes_waiting = loads_->waiting_count();
  }
  loads_->run_finished();
  subscribers_.notify(published);
}

// Evicts idle chunks now and then, and under memory pressure down to the budget's target;
// decides whether loads must wait. Pipeline thread.
void WorldPipeline::manage_memory(Clock::time_point now) {
  WorldState& st = *state_;
  const bool periodic = now - st.last_eviction > config_.evict_after / 4;
  // Under pressure, evict after every batch while eviction frees something or the world
  // grew since (terrain installed, meshes made); when it freed nothing and nothing came
  // (everything is in use), retry only now and then: the scan is not free.
  const size_t resident = resident_bytes();
  const bool pressure =
      budget_.should_evict(resident) && (last_eviction_freed_ || resident > resident_at_eviction_ ||
                                         now - st.last_eviction > kPressureRetry);
  if (periodic || pressure) {
    // Chunks whose meshes wait for the store stay: the batches are answered first.
    finish_pending(0);
    st.last_eviction = now;
    // The periodic pass drops only idle chunks; under pressure, down to the target.
    const size_t target =
        pressure ? budget_.evict_target(other_bytes_.load(std::memory_order_relaxed)) : SIZE_MAX;
    const size_t dropped = st.evict(meshes_, now, config_.evict_after,
                                    std::min(config_.evict_min_age, config_.evict_after), target,
                                    periodic ? SIZE_MAX : kPressureScan);
    last_eviction_freed_ = dropped > 0;
    resident_at_eviction_ = resident_bytes();
    std::lock_guard lock(stats_mutex_);
    stats_.chunks_evicted += dropped;
    stats_.loaded_chunks = st.chunks.size();
    stats_.modified_chunks = st.modified_count;
    stats_.chunk_bytes = st.chunks.memory_bytes();
  }
  // Blocked: no room even once the terrain on its way has landed (while it is on its way,
  // load passes only wait for it: see batch_ready).
  const size_t total = resident_bytes();
  const bool blocked = budget_.load_work(total, 1) == 0;
  if (blocked != loads_blocked_.load(std::memory_order_relaxed)) {
    if (blocked) {
      spdlog::warn(
          "memory budget: {} MiB accounted of {} MiB (--max-memory) and nothing left to evict; "
          "new chunk loads wait",
          total >> 20, budget_.max_bytes() >> 20);
      std::lock_guard lock(stats_mutex_);
      ++stats_.memory_blocked;
    } else {
      spdlog::info("memory budget: {} MiB accounted of {} MiB; loads resume", total >> 20,
                   budget_.max_bytes() >> 20);
    }
    loads_blocked_.store(blocked, std::memory_order_relaxed);
  }
}

}  // namespace vox::pipeline
