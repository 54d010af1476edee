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
  return memory_.budget().load_work(accounted_bytes(), full);
}

void WorldPipeline::take_view_updates(Inbox::State& in) {
  if (in.view_updates.empty()) return;
  for (const auto& [owner, view] : in.view_updates)
    state_->views.set(owner, view.first, view.second);
  in.view_updates.clear();
  loads_->drop_unviewed();
}

// The batch's load pass, planned on the world as its edits left it. Pipeline thread; the
// scheduler is read under the queue lock, and its cost callback touches only
// pipeline-thread state.
std::vector<LoadSlice> WorldPipeline::take_loads(LoadPlan& plan, Clock::time_point now) {
  return inbox_.locked([&](Inbox::State& in) -> std::vector<LoadSlice> {
    // The views whose requests this pass takes must be the ones eviction protects: a view
    // set after the batch started would otherwise have its meshed chunks passed over here
    // (nothing to load) yet evicted below, and the session would wait for them forever.
    take_view_updates(in);
    if (!in.scheduler.has_loads()) return {};
    return in.scheduler.take_loads(
        // Edits waiting to apply, or applied and waiting for the store to be answered: a
        // short pass, so that they are not held up behind it.
        load_work_allowed(in.scheduler.has_ordered() || batches_in_flight()),
        [&](ChunkCoord c) { return loads_->cost(c, plan, now); }, config_.load_scan_limit, now);
  });
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

// Evicts idle chunks now and then, and under memory pressure down to the budget's target
// (MemoryKeeper says when); decides whether loads must wait.
void WorldPipeline::manage_memory(Clock::time_point now) {
  WorldState& st = *state_;
  const MemoryBudget& budget = memory_.budget();
  if (const auto pass =
          memory_.due(now, resident_bytes(), other_bytes_.load(std::memory_order_relaxed))) {
    // Chunks whose meshes wait for the store stay: the batches are answered first.
    finish_pending(0);
    const size_t dropped =
        st.evict(meshes_, now, pass->idle, pass->min_age, pass->target_bytes, pass->max_scan);
    memory_.evicted(now, dropped, resident_bytes());
    std::lock_guard lock(stats_mutex_);
    stats_.chunks_evicted += dropped;
    stats_.loaded_chunks = st.chunks.size();
    stats_.modified_chunks = st.modified_count;
    stats_.chunk_bytes = st.chunks.memory_bytes();
  }
  // Blocked: no room even once the terrain on its way has landed (while it is on its way,
  // load passes only wait for it: see batch_ready).
  const size_t total = resident_bytes();
  if (!memory_.update_blocked(total)) return;
  if (memory_.loads_blocked()) {
    spdlog::warn(
        "memory budget: {} MiB accounted of {} MiB (--max-memory) and nothing left to evict; "
        "new chunk loads wait",
        total >> 20, budget.max_bytes() >> 20);
    std::lock_guard lock(stats_mutex_);
    ++stats_.memory_blocked;
  } else {
    spdlog::info("memory budget: {} MiB accounted of {} MiB; loads resume", total >> 20,
                 budget.max_bytes() >> 20);
  }
}

}  // namespace vox::pipeline
