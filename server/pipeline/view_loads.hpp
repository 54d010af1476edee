// The chunks load passes planned to mesh, until their neighbourhood is resident: the
// terrain they miss is generated in the background (TerrainPrefetcher) or, when it cannot
// take more, on the pipeline thread; checkpointed neighbours are read back from the store.
// A waiting chunk pins its 3x3x3 neighbourhood against eviction; one no view holds any more
// is dropped (a one-off load keeps its own). A request's callback runs once every chunk of
// the passes up to its own has been meshed. Bounded by the owners' load budgets, which
// paid for every waiting chunk. Pipeline thread only, but memory_bytes() and the counts.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <unordered_set>
#include <utility>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/terrain_prefetcher.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct WorldState;
class StoredChunkReader;

// What a load pass generates and meshes, built while the scheduler takes its chunks (so a
// chunk two owners want is counted once).
struct LoadPlan {
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> to_mesh, to_generate;
};

class ViewLoads {
 public:
  // `generate_threads` background threads (0: none, every chunk is generated on the
  // pipeline thread), at most `max_generating` chunks on their way; `ready` runs on one of
  // them when terrain is ready (it wakes the pipeline). `reader`: null without a store.
  ViewLoads(const world::TerrainGenerator& generator, WorldState& state, StoredChunkReader* reader,
            int generate_threads, size_t max_generating, std::function<void()> ready);
  ~ViewLoads();  // stops the background threads; their work is dropped

  // The load work chunk c needs in a pass (0: meshed already, or planned or waiting): its
  // mesh, and each neighbour to generate or read back not yet in the plan (which records
  // them). Load work units: kGenerateWork a chunk to generate or read, kMeshWork a mesh.
  static constexpr size_t kGenerateWork = 4, kMeshWork = 1;
  size_t cost(world::ChunkCoord c, LoadPlan& plan, Clock::time_point now);
  // The pass's slices were taken: their planned chunks wait, their callbacks after them.
  void wait_for(std::vector<LoadSlice>& slices, const LoadPlan& plan);
  // Installs the terrain generated in the background that a waiting chunk still needs;
  // returns how many chunks.
  size_t install_generated(Clock::time_point now);
  // The waiting chunks whose neighbourhood is resident now (they wait no more); the
  // terrain the others miss is asked of the background, and what it cannot take is
  // generated here (counted in delta).
  std::vector<world::ChunkCoord> take_meshable(Clock::time_point now, BatchCounts& delta);
  // Whether a waiting chunk needs a checkpointed neighbour the store failed to give back
  // in the last pass: the pipeline passes again (after the store's back-off) until it
  // can. Not the reader's failing(): a read of another chunk may have worked meanwhile.
  bool waiting_for_store() const { return store_failed_ && waiting(); }
  // Runs the callbacks of the requests whose every planned chunk is meshed.
  void run_finished();
  // Forgets the waiting chunks of views that no view holds any more (after views change).
  void drop_unviewed();
  // At stop: every callback still waiting runs.
  void run_all_callbacks();

  bool waiting() const { return !waiting_.empty(); }
  size_t waiting_count() const { return waiting_.size(); }
  size_t generating() const { return prefetcher_->pending_count(); }  // any thread
  // What is on its way: terrain in the background, and the meshes of the waiting chunks at
  // their worst case (so that passes taken meanwhile do not overrun the memory budget).
  size_t memory_bytes() const;

 private:
  bool needs_generating(world::ChunkCoord c) const;
  std::vector<world::ChunkCoord> collect_meshable(Clock::time_point now, BatchCounts& delta);

  struct Waiting {
    world::ChunkCoord coord;
    uint64_t pass;
    LoadOwner owner;
  };
  const world::TerrainGenerator& generator_;
  WorldState& state_;
  StoredChunkReader* const reader_;
  std::vector<Waiting> waiting_;
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> waiting_set_;
  std::vector<std::pair<uint64_t, std::function<void()>>> callbacks_;  // by pass
  uint64_t pass_ = 0;
  bool store_failed_ = false;  // a stored neighbour could not be read in the last pass
  std::unique_ptr<TerrainPrefetcher> prefetcher_;  // last: its threads stop first
};

}  // namespace vox::pipeline
