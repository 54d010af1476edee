// What the world pipeline is set to (PipelineConfig), what it reports (PipelineStats) and
// the durations it measures for metrics (PipelineObserver).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "server/pipeline/checkpoint_policy.hpp"
#include "server/pipeline/edit_ids.hpp"
#include "server/pipeline/lod_stage.hpp"
#include "server/pipeline/zone_authority.hpp"
#include "server/store/world_store.hpp"
#include "server/world/edit.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct PipelineConfig {
  uint64_t seed = 1;
  // The key of the world's edit ids (EditIds::of_player): a cluster's nodes share one.
  EditIds::Key edit_id_key = EditIds::random_key();
  world::TerrainParams terrain;
  int threads = 0;  // worker threads for apply/generate/mesh, 0 = all cores
  world::EditLimits limits;
  // Load work per pass (a chunk to generate is 4 units, one to mesh 1): about 25 ms cold
  // on 2 cores, so an edit arriving during a pass waits little; while edits wait, a pass
  // takes only the smaller budget.
  size_t load_pass_work = 192;
  size_t load_pass_work_while_edits_wait = 48;
  // Saved chunks unused this long (and whose mesh no one else holds) are dropped: they
  // regenerate from the seed, or are read back from the store. Modified chunks the store
  // does not have yet stay.
  std::chrono::milliseconds evict_after{std::chrono::minutes(2)};
  // Chunks used more recently than this are never evicted, even over the memory budget.
  std::chrono::milliseconds evict_min_age{std::chrono::seconds(1)};
  // Chunks one owner's edits may make a batch generate; more are refused kOverBudget. A
  // largest edit in untouched terrain needs 7^3 = 343.
  size_t max_generated_per_owner = 400;
  // Chunks the load scheduler considers per pass (most of a moved view is meshed already).
  size_t load_scan_limit = 16384;
  // Load work one session's views may take per second (4 units per chunk generated), and
  // at once: a first view fits the burst (radius 4: 2,925; the viewer's level-of-detail
  // view to the horizon, radius 4 and level 6: about 6,100, its level-0 part being every
  // level-0 chunk of the split level-1 ones); a view flood gets a fair share, not the
  // pipeline. 0: unlimited.
  double load_work_per_owner = 250;
  double load_burst_per_owner = 8000;
  // The same for all sessions from one address together (set_view's budget_group); it
  // outlives them until refilled, so reconnecting does not bring a fresh burst. 0: none.
  double load_work_per_address = 1000;
  double load_burst_per_address = 8000;
  size_t max_memory = 0;  // bytes; 0: no budget (see MemoryBudget)
  // Background threads (at a lower priority) that generate terrain for loads, so batches
  // only install it; 0: each load pass generates its terrain itself. -1: one per core.
  int generate_threads = -1;
  size_t max_generating = 2048;  // chunks queued or ready in the background at once
  // The durable world (null: edits live in memory only). The pipeline restores the world
  // from it when constructed and, from then on, is its only user: each batch's accepted
  // edits are appended in one transaction, durable before any result or mesh of the batch
  // is published; checkpointed chunks are read back from it. It must outlive the pipeline.
  store::WorldStore* store = nullptr;
  // A second connection to the same world for checkpoints, written in the background
  // while edits go on (null: written between batches on the pipeline thread, with
  // `store`). It must outlive the pipeline.
  store::WorldStore* checkpoint_store = nullptr;
  CheckpointLimits checkpoint;
  // A third connection, for rollbacks (pipeline/rollbacks.hpp; null: none are taken). It
  // must outlive the pipeline. A rollback holds at most max_rollback_chunks chunks (about
  // 100 KB each) while it recomputes.
  store::WorldStore* history_store = nullptr;
  size_t max_rollback_chunks = 2000;
  // A cluster node (docs/CLUSTER.md): the zones it may write and the records it must
  // apply (null: a single node). `store` is then the node's zone logs; no checkpoints are
  // written yet, so every changed chunk stays resident. It must outlive the pipeline.
  ZoneAuthority* zones = nullptr;
  // What checkpoints keep of the log they include: with keep_all every edit (an audit
  // trail), else the edits accepted within `window` (the history `voxel-cli world history`
  // lists; 0: none, the log is trimmed to what no checkpoint holds).
  LogRetention history;
  // After a failed append, edits are refused kStorageUnavailable without trying the store
  // again for this long.
  std::chrono::milliseconds store_retry{1000};
  // Level of detail: the stage's settings; between batches it meshes groups of
  // lod_group_chunks (in parallel) for up to lod_pass_time, stopping as soon as an edit
  // waits (then one group only): coarse levels never hold an edit up for long, and lag
  // behind when the server is saturated.
  LodStageConfig lod;
  size_t lod_group_chunks = 2;
  std::chrono::milliseconds lod_pass_time{10};
};

struct PipelineStats {
  uint64_t batches = 0, edits_applied = 0, edits_refused = 0, edits_refused_busy = 0,
           meshes_published = 0, chunks_generated = 0, chunks_evicted = 0, memory_blocked = 0;
  size_t loaded_chunks = 0, modified_chunks = 0, chunk_bytes = 0, mesh_count = 0, mesh_bytes = 0;
  size_t queued_edits = 0, queued_load_chunks = 0, load_owners = 0;
  size_t chunks_generating = 0;  // terrain queued or ready in the background
  size_t meshes_waiting = 0;     // loaded chunks waiting for their neighbours' terrain
  size_t cached_columns =
      0;                     // column heights left by earlier batches at the last batch's start (0)
  size_t session_bytes = 0;  // reported by set_session_bytes
  size_t unaccounted_bytes = 0;  // the allocator's heap beyond every part (MemoryKeeper)
  // Level-of-detail meshes (levels >= 1); their bytes include the generator grids kept.
  size_t lod_mesh_count = 0, lod_mesh_bytes = 0;
  // Per level (index 1 ..): LOD meshes made, of those re-meshed after edits, and those
  // published (they had changed).
  std::vector<uint64_t> lod_meshed, lod_remeshed, lod_published;
  size_t accounted_bytes = 0;  // chunks + meshes + sessions + unaccounted: what the budget counts
  bool loads_blocked = false;  // over the memory budget with nothing left to evict
  // The durable world: chunks the store has a checkpoint of, resident chunks changed since
  // (not evictable), checkpoints written, and the newest one's sequence number.
  size_t stored_chunks = 0, unsaved_chunks = 0;
  uint64_t checkpoints = 0, checkpoint_failures = 0, checkpoint_seq = 0;
};

// Durations the pipeline measures, for metrics. Called on the pipeline thread; must not
// block.
struct PipelineObserver {
  std::function<void(double seconds, size_t edits, size_t load_chunks)> batch;
  std::function<void(double seconds, size_t chunks)> remesh;
  // A transaction of the store's edit log (it may carry several batches' appends): how long
  // it took, its edits, and whether it failed.
  std::function<void(double commit_s, size_t edits, bool ok)> commit;
  // Per batch with an append: how long the pipeline thread stood waiting for it (0 when it
  // landed while later work went on).
  std::function<void(double waited_s)> commit_wait;
  // A checkpoint written (or failed): how long, how many chunks, their bytes.
  std::function<void(double seconds, size_t chunks, size_t bytes, bool ok)> checkpoint;
};

}  // namespace vox::pipeline
