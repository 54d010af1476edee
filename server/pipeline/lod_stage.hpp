// The pipeline's level-of-detail stage: which (chunk, seams) meshes the
// clients' layouts want, meshing the missing ones and re-meshing those an edit changed
// (coalesced by LodRemeshQueue), published into a LodMeshStore.
//
// Samples come from the generator at the chunk's own spacing, with every modified level-0
// chunk laid over it (OverlaySampler): so every level shows the edits. Modified chunks in
// a mesh's footprint that were evicted are read back from the store first.
//
// Pipeline thread only (it reads the chunk map while no batch writes it), except
// meshes(), which any thread may read. The pipeline runs it only while no batch waits for
// the store, so a LOD mesh never shows an edit that is not durable.
#pragma once

#include <tbb/enumerable_thread_specific.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/lod_mesh_store.hpp"
#include "server/pipeline/lod_remesh_queue.hpp"
#include "server/world/edit.hpp"
#include "server/world/grid_cache.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct WorldState;
struct LodWorker;
class StoredChunkReader;
using Clock = std::chrono::steady_clock;

struct LodStageConfig {
  int levels = 7;  // levels 0 .. levels-1 (level 0 is the pipeline's own)
  // A level-1 chunk re-meshed at most this often; coarser ones less (LodRemeshQueue).
  std::chrono::milliseconds remesh_interval{750};
  size_t max_pending_remesh = 65536;
  // Generator grids kept for re-meshing (an edit's re-mesh then computes no noise).
  size_t grid_cache_bytes = size_t{64} << 20;
};

class LodStage {
 public:
  // `reader`: reads evicted modified chunks back from the store (null: no store), and
  // says when to back off after a failed read.
  LodStage(const world::TerrainGenerator& generator, WorldState& state, LodStageConfig config,
           StoredChunkReader* reader = nullptr);
  ~LodStage();

  const LodMeshStore& meshes() const { return meshes_; }  // any thread

  // Learns which chunks differ from the generated terrain (stored, or modified and
  // resident): once the world is restored.
  void learn_modified();

  // The meshes `owner`'s layout needs, nearest first (empty: none; its session left).
  // Keys no owner wants any more are erased. Returns the keys new to the owner that are
  // published already (the owner is to hear of them: it may have looked before).
  std::vector<LodKey> set_wants(LoadOwner owner, std::vector<LodKey> keys);
  // A durable edit changed the samples of `box`: the wanted chunks it reaches are
  // re-meshed within the interval.
  void edited(const world::VoxelBox& box, Clock::time_point now);
  // Whether run() has something to do now, and when a re-mesh falls due.
  bool has_work(Clock::time_point now) const;
  std::optional<Clock::time_point> next_due() const;
  // Meshes up to `max_chunks` meshes (those the store put off, then re-meshes due, then
  // missing ones: take_missing) in parallel; publishes those that changed; returns their
  // keys. Reads at most 32 evicted chunks back from the store per pass; after a failed
  // read, does nothing for a second. `unsettled`: level-0 chunks holding edits that are
  // not durable yet; a mesh reading any of them is put off (to the next pass: `deferred`
  // counts them), since a LOD mesh never shows an edit that is not durable.
  struct RunResult {
    std::vector<LodKey> published;
    size_t deferred = 0;
  };
  RunResult run(Clock::time_point now, size_t max_chunks,
                const std::vector<world::ChunkCoord>& unsettled = {});

  // A pass put meshes off (they read edits not durable yet): true once that has lasted
  // kStarvation, when the pass is to wait for the store instead. ran(): a pass ran
  // without putting any off, or there was nothing to do.
  static constexpr auto kStarvation = std::chrono::milliseconds(250);
  // How long a first view goes before the others at most: a client that keeps changing
  // its layout before it has come cannot keep the front of the queue.
  static constexpr auto kFirstViewPriority = std::chrono::seconds(10);

  bool held_back(Clock::time_point now) {
    if (!held_back_since_) held_back_since_ = now;
    return now - *held_back_since_ >= kStarvation;
  }
  void ran() { held_back_since_.reset(); }

  // The owners whose layouts want each of these keys (pipeline thread): each owner with
  // its keys, by owner.
  std::vector<std::pair<LoadOwner, std::shared_ptr<const std::vector<LodKey>>>> route(
      const std::vector<LodKey>& published) const;

  size_t wanted() const { return wanters_.size(); }
  // Bytes of the meshes and of the generator grids kept (any thread).
  size_t memory_bytes() const { return meshes_.memory_bytes() + grids_.bytes(); }
  uint64_t remesh_dropped() const { return remesh_.dropped(); }
  // Meshes made of each level (changed or not), of those the re-meshes after edits (the
  // rest were new to the layouts), and those published, since the start (any thread).
  static constexpr int kCountedLevels = 21;
  uint64_t meshed(int level) const { return meshed_[level].load(std::memory_order_relaxed); }
  uint64_t remeshed(int level) const { return remeshed_[level].load(std::memory_order_relaxed); }
  uint64_t published(int level) const { return published_[level].load(std::memory_order_relaxed); }

 private:
  struct Owner {
    std::vector<LodKey> keys;
    size_t cursor = 0;  // keys before it were published when last looked at
    // Until every key of its first layout was published once: a player who sees nothing
    // until then (see take_missing).
    bool first_view = true;
    Clock::time_point arrived{};  // its first set_wants
  };
  void want(LoadOwner owner, const LodKey& k);
  void unwant(LoadOwner owner, const LodKey& k);
  // Up to `max` keys not published yet: the owners still waiting for their first view
  // (for up to kFirstViewPriority) first, the oldest (lowest id) first; then the others,
  // round robin, kOwnerTurn keys each. Every kSettledTurn-th call the others go first, so
  // that a stream of arrivals cannot starve a walking player's new chunks.
  void take_missing(Clock::time_point now, size_t max, std::vector<LodKey>& out);
  // Takes owner `o`'s missing keys, at most `turn` of them, into `out` (up to `max`);
  // advances its cursor past the published ones; returns how many it took.
  size_t take_keys(Owner& o, size_t turn, size_t max, std::vector<LodKey>& out,
                   std::unordered_set<LodKey, LodKeyHash>& taken) const;
  // Makes the modified chunks a mesh of `c` reads resident, reading at most `reads_left`
  // from the store (kLater: more than that are needed; kFailed: the store failed).
  enum class Resident { kReady, kLater, kFailed };
  Resident make_resident(const world::LodChunk& c, Clock::time_point now, size_t& reads_left);
  std::vector<LodKey> mesh_and_publish(std::vector<LodKey> keys);
  // Meshes `k` from the samples in w.block (gathered for its seams or more); null when
  // the published mesh is the same. Any worker thread.
  std::shared_ptr<MeshVersion> mesh_variant(const LodKey& k, LodWorker& w) const;

  const world::TerrainGenerator& generator_;
  WorldState& state_;
  LodStageConfig config_;
  LodMeshStore meshes_;
  LodRemeshQueue remesh_;
  std::unordered_map<LoadOwner, Owner> owners_;
  // The owners wanting each key (an owner once per key it wants).
  std::unordered_map<LodKey, std::vector<LoadOwner>, LodKeyHash> wanters_;
  // Per chunk, the seams variants wanted (each counted once however many owners).
  std::map<world::LodChunk, std::vector<world::LodSeams>> variants_;
  bool missing_ = false;  // an owner may want a key not published yet
  // Chunks that may differ from the generated terrain: stored ones and those edits
  // changed (an unmodified one found here is dropped when its footprint is prepared).
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> modified_;
  uint64_t next_version_ = 1;
  tbb::enumerable_thread_specific<std::unique_ptr<LodWorker>> workers_;
  world::GridCache grids_;
  size_t next_owner_ = 0;       // round robin
  uint64_t missing_calls_ = 0;  // take_missing calls (every kSettledTurn-th: settled first)
  // Some owner's first view was not all published when take_missing last looked (or an
  // owner came since): re-meshes wait their turn (lod_remesh_turn).
  bool first_views_wait_ = false;
  uint64_t passes_ = 0;  // run() calls
  StoredChunkReader* const reader_;
  // After a failed read of the store: not before this (else a time long past).
  Clock::time_point store_retry_at() const;
  std::vector<world::LodChunk> retry_;  // put off by the store: meshed first next time
  std::optional<Clock::time_point> held_back_since_;  // see held_back()
  std::array<std::atomic<uint64_t>, kCountedLevels> meshed_{}, remeshed_{}, published_{};
};

}  // namespace vox::pipeline
