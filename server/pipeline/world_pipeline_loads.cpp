// The world pipeline's load pass and its memory management: what a batch does besides
// its edits. Pipeline thread (see world_pipeline.hpp).
#include <spdlog/spdlog.h>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

// Load work units: a chunk to generate, a chunk to mesh.
constexpr size_t kGenerateWork = 4;
constexpr size_t kMeshWork = 1;

}  // namespace

// With the terrain and the meshes on their way at their worst case, so that load passes
// taken while earlier ones wait for terrain do not overrun the memory budget.
size_t WorldPipeline::accounted_bytes() const {
  return resident_bytes() + prefetcher_->memory_bytes() +
         (checkpoints_ ? checkpoints_->memory_bytes() : 0) +
         waiting_meshes_.size() * MemoryBudget::kBytesPerMesh;
}

size_t WorldPipeline::resident_bytes() const {
  return state_->chunks.memory_bytes() + meshes_.memory_bytes() + lod_->memory_bytes() +
         other_bytes_.load(std::memory_order_relaxed);
}

bool WorldPipeline::needs_generating(ChunkCoord c) const {
  return !state_->info.count(c) && !state_->stored.count(c) && !prefetcher_->pending(c);
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
  drop_unviewed_waiting();
}

// A waiting chunk is kept while any view holds it, whoever planned it: a second view that
// wanted it found it waiting and will not ask again (its cost was 0).
void WorldPipeline::drop_unviewed_waiting() {
  std::erase_if(waiting_meshes_, [&](const WaitingMesh& w) {
    if ((w.owner & BatchScheduler::kUnlimitedOwners) || state_->views.viewed(w.coord)) return false;
    waiting_set_.erase(w.coord);
    state_->unpin_neighbourhood(w.coord);
    return true;
  });
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
      // Edits waiting to apply, or applied and waiting for the store to be answered: a
      // short pass, so that they are not held up behind it.
      load_work_allowed(scheduler_.has_ordered() || !pending_.empty()),
      [&](ChunkCoord c) {
        if (plan.to_mesh.count(c) || waiting_set_.count(c)) return size_t{0};
        if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
          it->second.last_used = now;  // meshed already: only marked as viewed
          return size_t{0};
        }
        size_t work = kMeshWork;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const ChunkCoord n = c.offset(dx, dy, dz);
              // A stored chunk costs as much: read and decompressed on this thread.
              const bool costs = needs_generating(n) || (!st.info.count(n) && st.stored.count(n));
              if (costs && plan.to_generate.insert(n).second) work += kGenerateWork;
            }
        plan.to_mesh.insert(c);
        return work;
      },
      config_.load_scan_limit, now);
}

// Installs the terrain the background has generated that a waiting mesh still needs
// (unless a batch generated the chunk itself meanwhile: it is the same); terrain of views
// that moved on or closed is dropped. Returns the number installed.
size_t WorldPipeline::install_generated(Clock::time_point now) {
  WorldState& st = *state_;
  size_t installed = 0;
  for (auto& [c, chunk] : prefetcher_->take_ready()) {
    if (st.info.count(c) || !st.pins.count(c) || st.stored.count(c)) continue;
    st.chunks.insert(c, std::move(chunk));
    st.info[c] = {.last_used = now};
    ++installed;
  }
  return installed;
}

// The waiting chunks whose neighbourhood is loaded now (removed from the waiting list);
// the terrain the others still miss is asked of the background, and what it cannot take
// is generated here.
std::vector<ChunkCoord> WorldPipeline::take_meshable(Clock::time_point now, PipelineStats& delta) {
  WorldState& st = *state_;
  std::vector<ChunkCoord> meshable, missing;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> asked;
  std::erase_if(waiting_meshes_, [&](const WaitingMesh& w) {
    bool complete = true;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const ChunkCoord n = w.coord.offset(dx, dy, dz);
          if (auto it = st.info.find(n); it != st.info.end()) {
            it->second.last_used = now;  // kept until the mesh is made
            continue;
          }
          // Checkpointed: read back here (a store that fails is tried again next pass).
          if (st.stored.count(n) && reader_->try_load(st, n, now)) continue;
          complete = false;
          if (!st.stored.count(n) && asked.insert(n).second && !prefetcher_->pending(n))
            missing.push_back(n);
        }
    if (!complete) return false;
    meshable.push_back(w.coord);
    waiting_set_.erase(w.coord);
    st.unpin_neighbourhood(w.coord);
    return true;
  });
  if (!missing.empty()) {
    const std::vector<ChunkCoord> refused = prefetcher_->request(missing);
    if (!refused.empty()) {  // generated here: what waited only for them is meshable now
      delta.chunks_generated += st.ensure_loaded(refused, generator_, now);
      for (const ChunkCoord& c : take_meshable(now, delta)) meshable.push_back(c);
    }
  }
  return meshable;
}

// Runs the load callbacks of passes whose every planned chunk is meshed.
void WorldPipeline::run_finished_loads() {
  uint64_t oldest = UINT64_MAX;
  for (const WaitingMesh& w : waiting_meshes_) oldest = std::min(oldest, w.pass);
  std::erase_if(waiting_done_, [&](auto& entry) {
    if (entry.first >= oldest) return false;
    entry.second();
    return true;
  });
}

// One load pass: installs the terrain generated in the background, queues what the
// planned chunks still miss, meshes and publishes every waiting chunk whose neighbourhood
// is complete, then runs the finished requests' callbacks.
void WorldPipeline::process_loads(std::vector<LoadSlice>& loads, LoadPlan& plan,
                                  Clock::time_point now, PipelineStats& batch) {
  PipelineStats delta;
  if (!loads.empty()) {
    ++load_pass_;
    for (LoadSlice& slice : loads) {
      for (const ChunkCoord& c : slice.chunks) {  // the chunks the pass planned to mesh
        if (!plan.to_mesh.count(c) || !waiting_set_.insert(c).second) continue;
        waiting_meshes_.push_back({c, load_pass_, slice.owner});
        state_->pin_neighbourhood(c);
      }
      if (slice.done) waiting_done_.emplace_back(load_pass_, std::move(slice.done));
    }
  }
  // After the new waiting chunks pinned their neighbourhoods: terrain ready for them is kept.
  delta.chunks_generated += install_generated(now);
  std::vector<ChunkCoord> published;
  if (!waiting_meshes_.empty()) {
    std::vector<ChunkCoord> dirty = take_meshable(now, delta);
    finish_landed();  // not held up by the meshing
    if (near_pending_edits(dirty)) finish_pending(batch, 0);
    published = remesh_and_publish(dirty);
    delta.meshes_published += published.size();
  }
  commit_stats(delta, batch);
  {
    std::lock_guard lock(stats_mutex_);
    stats_.chunks_generating = prefetcher_->pending_count();
    stats_.meshes_waiting = waiting_meshes_.size();
  }
  run_finished_loads();
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
    PipelineStats counts;
    finish_pending(counts, 0);
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
