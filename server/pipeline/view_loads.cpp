#include "server/pipeline/view_loads.hpp"

#include <algorithm>

#include "server/pipeline/memory_budget.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

ViewLoads::ViewLoads(const world::TerrainGenerator& generator, WorldState& state,
                     StoredChunkReader* reader, int generate_threads, size_t max_generating,
                     std::function<void()> ready)
    : generator_(generator),
      state_(state),
      reader_(reader),
      prefetcher_(std::make_unique<TerrainPrefetcher>(generator, generate_threads, max_generating,
                                                      MemoryBudget::kBytesPerChunk,
                                                      std::move(ready))) {}

ViewLoads::~ViewLoads() = default;

size_t ViewLoads::memory_bytes() const {
  return prefetcher_->memory_bytes() + waiting_.size() * MemoryBudget::kBytesPerMesh;
}

bool ViewLoads::needs_generating(ChunkCoord c) const {
  return !state_.info.count(c) && !state_.stored.count(c) && !prefetcher_->pending(c);
}

size_t ViewLoads::cost(ChunkCoord c, LoadPlan& plan, Clock::time_point now) {
  WorldState& st = state_;
  if (plan.to_mesh.count(c) || waiting_set_.count(c)) return 0;
  if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
    it->second.last_used = now;  // meshed already: only marked as viewed
    return 0;
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
}

void ViewLoads::wait_for(std::vector<LoadSlice>& slices, const LoadPlan& plan) {
  if (slices.empty()) return;
  ++pass_;
  for (LoadSlice& slice : slices) {
    for (const ChunkCoord& c : slice.chunks) {  // the chunks the pass planned to mesh
      if (!plan.to_mesh.count(c) || !waiting_set_.insert(c).second) continue;
      waiting_.push_back({c, pass_, slice.owner});
      state_.pin_neighbourhood(c);
    }
    if (slice.done) callbacks_.emplace_back(pass_, std::move(slice.done));
  }
}

// Unless a batch generated the chunk itself meanwhile (it is the same): terrain of views
// that moved on or closed is dropped.
size_t ViewLoads::install_generated(Clock::time_point now) {
  WorldState& st = state_;
  size_t installed = 0;
  for (auto& [c, chunk] : prefetcher_->take_ready()) {
    if (st.info.count(c) || !st.pins.count(c) || st.stored.count(c)) continue;
    st.chunks.insert(c, std::move(chunk));
    st.info[c] = {.last_used = now};
    ++installed;
  }
  return installed;
}

std::vector<ChunkCoord> ViewLoads::take_meshable(Clock::time_point now, BatchCounts& delta) {
  store_failed_ = false;
  return collect_meshable(now, delta);
}

std::vector<ChunkCoord> ViewLoads::collect_meshable(Clock::time_point now, BatchCounts& delta) {
  WorldState& st = state_;
  std::vector<ChunkCoord> meshable, missing;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> asked;
  std::erase_if(waiting_, [&](const Waiting& w) {
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
          if (st.stored.count(n)) {
            if (reader_->try_load(st, n, now)) continue;
            store_failed_ = true;
          }
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
      for (const ChunkCoord& c : collect_meshable(now, delta)) meshable.push_back(c);
    }
  }
  return meshable;
}

void ViewLoads::run_finished() {
  uint64_t oldest = UINT64_MAX;
  for (const Waiting& w : waiting_) oldest = std::min(oldest, w.pass);
  std::erase_if(callbacks_, [&](auto& entry) {
    if (entry.first >= oldest) return false;
    entry.second();
    return true;
  });
}

// A waiting chunk is kept while any view holds it, whoever planned it: a second view that
// wanted it found it waiting and will not ask again (its cost was 0).
void ViewLoads::drop_unviewed() {
  std::erase_if(waiting_, [&](const Waiting& w) {
    if ((w.owner & BatchScheduler::kUnlimitedOwners) || state_.views.viewed(w.coord)) return false;
    waiting_set_.erase(w.coord);
    state_.unpin_neighbourhood(w.coord);
    return true;
  });
}

void ViewLoads::run_all_callbacks() {
  for (auto& [pass, done] : callbacks_) done();
  callbacks_.clear();
}

}  // namespace vox::pipeline
