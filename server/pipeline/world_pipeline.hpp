// The single logical writer of chunk densities. Edits, view loads and inspections arrive
// from any thread; a BatchScheduler decides what each batch holds (every queued edit, then
// loads round robin over their owners within a work budget). One pipeline thread applies a
// batch (fanning out over chunks with TBB), re-meshes the dirty chunks in parallel,
// publishes each changed mesh as a new immutable version, then reports results and
// notifies subscribers. Readers use meshes() and never block it. A MemoryBudget decides
// when unused chunks are evicted and when loads must wait.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "server/mesh/region_mesher.hpp"
#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/checkpoint_policy.hpp"
#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/durable_commit.hpp"
#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/lod_stage.hpp"
#include "server/pipeline/memory_budget.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/store_appender.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/subscribers.hpp"
#include "server/pipeline/view_loads.hpp"
#include "server/store/world_store.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct WorldState;

struct PipelineConfig {
  uint64_t seed = 1;
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
  // at once: a first radius-4 view fits the burst; a view flood gets a fair share, not the
  // pipeline. 0: unlimited.
  double load_work_per_owner = 250;
  double load_burst_per_owner = 4000;
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
  // Checkpoints leave the log whole (an audit trail of every edit) instead of deleting
  // what they include.
  bool keep_log = false;
  // After a failed append, edits are refused kStorageUnavailable without trying the store
  // again for this long.
  std::chrono::milliseconds store_retry{1000};
  // Level of detail (issue 16): the stage's settings; between batches it meshes groups of
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
      0;                   // column heights left by earlier batches at the last batch's start (0)
  size_t other_bytes = 0;  // reported by set_other_bytes (sessions)
  // Level-of-detail meshes (levels >= 1); their bytes include the generator grids kept.
  size_t lod_mesh_count = 0, lod_mesh_bytes = 0;
  // Per level (index 1 ..): LOD meshes made, of those re-meshed after edits, and those
  // published (they had changed).
  std::vector<uint64_t> lod_meshed, lod_remeshed, lod_published;
  size_t accounted_bytes = 0;  // chunks + meshes + other
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

class WorldPipeline {
 public:
  using EditCallback = std::function<void(const EditResult&)>;
  using Subscriber = Subscribers::Subscriber;

  explicit WorldPipeline(PipelineConfig config, PipelineObserver observer = {});
  ~WorldPipeline();  // stop()
  WorldPipeline(const WorldPipeline&) = delete;
  WorldPipeline& operator=(const WorldPipeline&) = delete;

  // Any thread. `done` runs on the pipeline thread once the edit's meshes are published
  // (or it was refused); it must not block. Every queued edit is in the next batch.
  // `owner` (a session id; 0 for none) bounds the terrain its edits may make the pipeline
  // generate in one batch.
  // `author`: the player id the edit is logged under; `bypass_regions`: an admin's edit,
  // which protected regions do not hold back.
  void submit(world::Edit edit, EditCallback done, LoadOwner owner = 0, std::string author = {},
              bool bypass_regions = false);
  std::future<EditResult> submit(world::Edit edit);
  // Any thread. Adds or removes a protected region in order with the edits around it;
  // `task.done` runs on the pipeline thread once the change is durable (or refused).
  void change_regions(RegionTask task);
  // Any thread: the protected regions in force, as of the last durable change.
  std::shared_ptr<const std::vector<world::Region>> regions() const { return regions_.published(); }
  // Any thread. Generates and meshes whatever of the box is missing; `done` runs on the
  // pipeline thread once every chunk of the box has a published mesh.
  void load(mesh::ChunkBox box, std::function<void()> done);
  std::future<void> load(mesh::ChunkBox box);
  // Any thread. The view of `owner` (a session id, below 2^63) becomes the ball of
  // `radius` chunks around `center`: its queued loads are replaced by the new view's
  // missing chunks, nearest first. Newly published meshes reach subscribers.
  // `budget_group`: the owner's address (0: none), for the per-address load budget.
  // `keep`: of the ball, only the chunks it is true for (a level-of-detail layout's level
  // 0); the whole ball stays safe from eviction.
  void set_view(LoadOwner owner, world::ChunkCoord center, int radius, uint64_t budget_group = 0,
                const std::function<bool(world::ChunkCoord)>& keep = {});
  // Any thread: drops the owner's queued loads and its level-of-detail view (its session
  // closed).
  void drop_view(LoadOwner owner);
  // Any thread. The level-of-detail meshes (levels >= 1, with their seams) `owner`'s
  // layout needs, nearest first, replacing its previous ones. They are meshed between
  // batches, re-meshed after edits (coalesced, see LodStageConfig), and each new version
  // reaches the LOD subscribers.
  void set_lod_view(LoadOwner owner, std::vector<LodKey> keys);
  const LodMeshStore& lod_meshes() const { return lod_->meshes(); }  // any thread
  // Like subscribe(), for level-of-detail meshes (unsubscribe() drops either): the keys
  // published, routed to the owners whose layouts want them (subscribers.hpp). Routing
  // follows the wants the pipeline has taken (set_lod_view's, between batches).
  using LodKeys = pipeline::LodKeys;
  using LodPublication = pipeline::LodPublication;
  using LodSubscriber = Subscribers::LodSubscriber;
  uint64_t subscribe_lod(LodSubscriber s) {  // any thread
    return subscribers_.subscribe_lod(std::move(s));
  }
  // Runs fn on the pipeline thread between batches, and waits for it (tests, persistence).
  void inspect(std::function<void(const world::ChunkMap&)> fn);

  const MeshStore& meshes() const { return meshes_; }  // any thread
  // Subscribers run on the pipeline thread after each batch with the chunks that got a
  // new version; they must not block (post to your own executor).
  uint64_t subscribe(Subscriber s) { return subscribers_.subscribe(std::move(s)); }  // any thread
  void unsubscribe(uint64_t id) { subscribers_.unsubscribe(id); }                    // any thread
  PipelineStats stats() const;                                                       // any thread
  // Any thread: bytes held outside the pipeline (sessions' state), counted in the memory
  // budget.
  void set_other_bytes(size_t bytes) { other_bytes_.store(bytes, std::memory_order_relaxed); }
  const PipelineConfig& config() const { return config_; }
  // Finishes the batch in flight, refuses queued edits (kShuttingDown), runs queued load
  // callbacks, writes a checkpoint of every unsaved chunk (with a store), joins the
  // thread. Idempotent.
  void stop();

 private:
  // Chunks one eviction pass under memory pressure looks at (about 1 ms): a batch never
  // stalls on a scan of the whole world.
  static constexpr size_t kPressureScan = 4096;
  // While over the memory budget, eviction is retried at most this often.
  static constexpr auto kPressureRetry = std::chrono::milliseconds(250);

  void enqueue(OrderedTask task);
  void run();
  bool batch_ready();        // under queue_mutex_
  void take_view_updates();  // under queue_mutex_, pipeline thread
  std::vector<LoadSlice> take_loads(LoadPlan& plan, Clock::time_point now);  // pipeline thread
  size_t load_work_allowed(bool edits_waiting);
  void process_ordered(std::vector<OrderedTask>& tasks, Clock::time_point now);
  void process_loads(std::vector<LoadSlice>& loads, LoadPlan& plan, Clock::time_point now);
  // Adds `delta` to the stats and to the batch's counts; refreshes the loaded-chunk figures.
  void count(const BatchCounts& delta);
  world::RefusalReason apply_edit_task(const world::Edit& edit, Clock::time_point now,
                                       size_t max_generate, std::vector<world::ChunkCoord>& dirtied,
                                       EditResult& result, Undo* undo = nullptr,
                                       std::span<const world::VoxelBox> keep = {});
  // `edited_at`: none for a load's meshes.
  std::vector<world::ChunkCoord> remesh_and_publish(std::vector<world::ChunkCoord>& dirty,
                                                    const EditTimes* edited_at = nullptr);
  // remesh_and_publish in two steps: `dirty` is sorted and deduplicated, each chunk meshed
  // (in parallel); publish() gives the changed meshes their versions.
  FreshMeshes remesh(std::vector<world::ChunkCoord>& dirty);
  std::vector<world::ChunkCoord> publish(const std::vector<world::ChunkCoord>& dirty,
                                         FreshMeshes& fresh, const EditTimes* edited_at);
  void roll_back(Undo& undo);

  // A batch of edits applied and re-meshed (pipeline thread). With a store its accepted
  // edits are appended (commit_) while the pipeline goes on (the next batches apply, load
  // passes run); nothing of it is published and no edit of it answered until the append
  // is durable.
  // Batches in flight are at most this many: past it, the pipeline waits for the oldest.
  static constexpr size_t kMaxPendingBatches = 3;
  // After re-meshing, a batch waits this long (from its append's start) for the append
  // before the pipeline goes on: most appends land by then and are answered at once; a
  // slow one no longer holds up the load pass and the next batches (answered after them).
  // An edit arriving ends the wait: it is not held up behind another batch's fsync.
  static constexpr auto kAnswerWait = std::chrono::milliseconds(6);
  EditBatch apply_batch(std::vector<OrderedTask>& tasks, Clock::time_point now);
  // After a failed append that carried region changes (it may have landed or not): an
  // append of the whole region table alone, once the store may be tried again (or, with
  // `now_anyway`, at stop). Pipeline thread.
  void repair_regions(Clock::time_point now, bool now_anyway = false);
  // Whether batches wait for the store (their edits are applied, not yet durable).
  bool batches_in_flight() const { return commit_ && !commit_->empty(); }
  // Answers the batches whose appends landed, oldest first, waiting while more than `keep`
  // are in flight (0: every batch is answered when it returns).
  void finish_pending(size_t keep) {
    if (commit_) commit_->finish(keep);
  }
  // After the newest pending batch re-meshed: answers the pending batches as their appends
  // land, until every one is answered, an edit arrives or `until`; then, past
  // kMaxPendingBatches, waits for the oldest (pipeline thread; takes queue_mutex_).
  void wait_for_answer(Clock::time_point until);
  void finish_landed();  // finish_pending without waiting, between batches
  // Publishes a durable batch's meshes, or refuses its accepted edits (not durable: it was
  // rolled back), then answers its edits and notifies the subscribers.
  void answer(EditBatch& b, bool durable);
  // Level of detail (world_pipeline_lod.cpp; pipeline thread): whether the stage may run
  // now (no batch waits for the store), and one pass of it.
  bool lod_ready(Clock::time_point now) const;
  void lod_pass(Clock::time_point now);
  // After a durable batch: its accepted edits reach the coarse levels.
  void lod_edited(const EditBatch& b, Clock::time_point now);
  void notify_lod(const std::vector<LodKey>& published);  // routed to their owners
  void lod_stats(PipelineStats& s) const;                 // its part of stats(); any thread
  // The newest mesh of `c`: a pending batch's, else the published one.
  MeshVersionPtr newest_mesh(world::ChunkCoord c) const;
  // Constructor: learns which chunks are stored and replays the log after their
  // checkpoint (loading the chunks it touches).
  void restore_from_store();
  void preload_stored(const std::vector<store::LoggedEdit>& tail);
  // Pipeline thread: takes a finished checkpoint's result; starts the next one when due
  // (the batches in flight answered first: a checkpoint holds every applied edit).
  void checkpoint_if_due(Clock::time_point now);
  void start_checkpoint(Clock::time_point now);
  // The edits in the log no finished checkpoint covers, the pending batches' included.
  uint64_t logged_since_checkpoint() const;
  void finish_checkpoint(const CheckpointResult& r, Clock::time_point now);  // and its stats
  void final_checkpoint();  // at stop: everything unsaved, waited for
  void drain_after_stop();
  void manage_memory(Clock::time_point now);
  size_t accounted_bytes() const;  // pipeline thread
  size_t resident_bytes() const;   // the same without what is on its way

  const PipelineConfig config_;
  const PipelineObserver observer_;
  const world::TerrainGenerator generator_;
  const MemoryBudget budget_;
  MeshStore meshes_;

  // Guards scheduler_, stopping_, view_updates_, lod_updates_ and generated_ready_. Held while
  // taking loads, it may nest the prefetcher's (leaf) mutex, never the other way round.
  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  BatchScheduler scheduler_;
  bool stopping_ = false;
  uint64_t next_anonymous_owner_ = 1;  // under queue_mutex_
  // Views set or dropped since the last batch (radius -1: dropped); under queue_mutex_.
  std::unordered_map<LoadOwner, std::pair<world::ChunkCoord, int>> view_updates_;
  std::atomic<bool> loads_blocked_{false};  // over budget with nothing evictable
  std::atomic<size_t> other_bytes_{0};

  Subscribers subscribers_;

  mutable std::mutex stats_mutex_;  // leaf lock
  PipelineStats stats_;

  bool generated_ready_ = false;  // under queue_mutex_: the prefetcher has chunks for us

  std::unique_ptr<WorldState> state_;  // pipeline thread only
  // Checkpointed chunks read back (with a store); pipeline thread only.
  std::unique_ptr<StoredChunkReader> reader_;
  std::unique_ptr<LodStage> lod_;  // pipeline thread only, but lod_meshes()
  // Level-of-detail views set or dropped since the last batch (empty: dropped); under
  // queue_mutex_.
  std::unordered_map<LoadOwner, std::vector<LodKey>> lod_updates_;
  // Since when the stage had work but a batch waiting for the store held it back
  // (pipeline thread); past kLodStarvation the pass waits for the appends.
  std::optional<Clock::time_point> lod_starved_since_;
  static constexpr auto kLodStarvation = std::chrono::milliseconds(250);
  bool last_eviction_freed_ = false;  // pipeline thread only
  size_t resident_at_eviction_ = 0;   // resident_bytes() after the last eviction; pipeline thread
  bool evicted_for_edits_ = false;    // this batch made room for edits; pipeline thread
  BatchCounts batch_counts_;    // of the batch in hand, for the slow-batch log; pipeline thread
  ProtectedRegions regions_;    // pipeline thread, but regions()
  bool append_landed_ = false;  // under queue_mutex_: a pending batch may be answered
  // With a store; pipeline thread, but memory_bytes(). Reset by stop() once thread_ ended.
  std::unique_ptr<Checkpoints> checkpoints_;
  // With a store; pipeline thread. Reset by stop() once thread_ has ended.
  std::unique_ptr<DurableCommit> commit_;
  std::thread thread_;
  // Chunks load passes planned to mesh, waiting for their terrain; pipeline thread. Reset by
  // stop() once thread_ has ended (its threads wake the pipeline).
  std::unique_ptr<ViewLoads> loads_;
};

}  // namespace vox::pipeline
