// The world pipeline's load pass and its memory management: what a batch does besides
// its edits. Pipeline thread (see world_pipeline.hpp).
#include <spdlog/spdlog.h>

#include "pipeline/world_pipeline.hpp"
#include "pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

// Load work units: a chunk to generate, a chunk to mesh.
constexpr size_t kGenerateWork = 4;
constexpr size_t kMeshWork = 1;

}  // namespace

size_t WorldPipeline::accounted_bytes() const {
  return state_->chunks.memory_bytes() + meshes_.memory_bytes() +
         other_bytes_.load(std::memory_order_relaxed);
}

size_t WorldPipeline::load_work_allowed(bool edits_waiting) {
  const size_t full =
      edits_waiting ? config_.load_pass_work_while_edits_wait : config_.load_pass_work;
  return budget_.load_work(accounted_bytes(), full);
}

void WorldPipeline::take_view_updates() {
  for (const auto& [owner, view] : view_updates_) state_->views.set(owner, view.first, view.second);
  view_updates_.clear();
}

// The batch's load pass, planned on the world as its edits left it. Pipeline thread; the
// scheduler is read under the queue lock, and its cost callback touches only
// pipeline-thread state.
std::vector<LoadSlice> WorldPipeline::take_loads(LoadPlan& plan, Clock::time_point now) {
  WorldState& st = *state_;
  std::lock_guard lock(queue_mutex_);
  // The views whose requests this pass takes must be the ones eviction protects: a view
  // set after the batch started would otherwise have its meshed chunks passed over here
  // (nothing to load) yet evicted below, and the session would wait for them forever.
  take_view_updates();
  if (!scheduler_.has_loads()) return {};
  return scheduler_.take_loads(
      load_work_allowed(scheduler_.has_ordered()),
      [&](ChunkCoord c) {
        if (plan.to_mesh.count(c)) return size_t{0};
        if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
          it->second.last_used = now;  // meshed already: only marked as viewed
          return size_t{0};
        }
        size_t work = kMeshWork;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const ChunkCoord n = c.offset(dx, dy, dz);
              if (!st.info.count(n) && plan.to_generate.insert(n).second) work += kGenerateWork;
            }
        plan.to_mesh.insert(c);
        return work;
      },
      config_.load_scan_limit, now);
}

// One load pass: generates the missing chunks the plan needs (parallel over columns),
// meshes and publishes the planned chunks, then runs the finished requests' callbacks.
void WorldPipeline::process_loads(std::vector<LoadSlice>& loads, LoadPlan& plan,
                                  Clock::time_point now, PipelineStats& batch) {
  if (loads.empty()) return;
  WorldState& st = *state_;
  PipelineStats delta;
  delta.chunks_generated += st.ensure_loaded(
      std::vector<ChunkCoord>(plan.to_generate.begin(), plan.to_generate.end()), generator_, now);
  std::vector<ChunkCoord> dirty(plan.to_mesh.begin(), plan.to_mesh.end());
  for (const ChunkCoord& c : dirty) st.info.at(c).last_used = now;  // generated just above
  const std::vector<ChunkCoord> published = remesh_and_publish(dirty);
  delta.meshes_published += published.size();
  commit_stats(delta, batch);
  for (LoadSlice& slice : loads) {
    if (slice.done) slice.done();
  }
  notify_subscribers(published);
}

// Evicts idle chunks now and then, and under memory pressure down to the budget's target;
// decides whether loads must wait. Pipeline thread.
void WorldPipeline::manage_memory(Clock::time_point now) {
  WorldState& st = *state_;
  const bool periodic = now - st.last_eviction > config_.evict_after / 4;
  // Under pressure, evict after every batch while eviction frees something; when it freed
  // nothing (everything is in use), retry only now and then: the scan is not free.
  const bool pressure = budget_.should_evict(accounted_bytes()) &&
                        (last_eviction_freed_ || now - st.last_eviction > kPressureRetry);
  if (periodic || pressure) {
    st.last_eviction = now;
    // The periodic pass drops only idle chunks; under pressure, down to the target.
    const size_t target = pressure ? budget_.evict_target(other_bytes_.load(std::memory_order_relaxed))
                                   : SIZE_MAX;
    const size_t dropped =
        st.evict(meshes_, now, config_.evict_after,
                 std::min(config_.evict_min_age, config_.evict_after), target,
                 periodic ? SIZE_MAX : kPressureScan);
    last_eviction_freed_ = dropped > 0;
    std::lock_guard lock(stats_mutex_);
    stats_.chunks_evicted += dropped;
    stats_.loaded_chunks = st.chunks.size();
    stats_.chunk_bytes = st.chunks.memory_bytes();
  }
  const size_t total = accounted_bytes();
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
