// The single logical writer of chunk densities. Edits, view loads and inspections arrive
// from any thread through the Inbox; a BatchScheduler decides what each batch holds (every
// queued edit, then loads round robin over their owners within a work budget). One
// pipeline thread applies a batch (fanning out over chunks with TBB), re-meshes the dirty
// chunks in parallel, has the batch made durable (DurableCommit), publishes each changed
// mesh as a new immutable version, then reports results and notifies subscribers. Readers
// use meshes() and never block it. Between batches its parts take their turns: loads
// (ViewLoads), the level-of-detail stage, eviction (MemoryKeeper), checkpoints.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include "server/mesh/region_mesher.hpp"
#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/durable_commit.hpp"
#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/edit_step.hpp"
#include "server/pipeline/inbox.hpp"
#include "server/pipeline/lod_stage.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/pipeline_config.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/subscribers.hpp"
#include "server/pipeline/view_loads.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct WorldState;

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
  // The batch loop and the rules between its parts (world_pipeline.cpp).
  void run();
  bool batch_ready(Inbox::State& in);                                 // under the inbox's lock
  std::chrono::milliseconds idle_wait(const Inbox::State& in) const;  // likewise
  void between_batches(Clock::time_point now);
  void take_view_updates(Inbox::State& in);  // likewise
  void drain_after_stop();
  void enqueue(OrderedTask task);
  // Adds `delta` to the stats and to the batch's counts; refreshes the loaded-chunk figures.
  void count(const BatchCounts& delta);

  // Edits (world_pipeline.cpp; one edit: edit_step.hpp).
  void process_ordered(std::vector<OrderedTask>& tasks, Clock::time_point now);
  EditBatch apply_batch(std::vector<OrderedTask>& tasks, Clock::time_point now);
  EditWorld edit_world();  // what apply_edit_step reads and writes
  void roll_back(Undo& undo);
  // Publishes a durable batch's meshes, or refuses its accepted edits (not durable: it was
  // rolled back), then answers its edits and notifies the subscribers.
  void answer(EditBatch& b, bool durable);

  // Durable commit (world_pipeline_commit.cpp). Batches in flight are at most
  // kMaxPendingBatches: past it, the pipeline waits for the oldest. After re-meshing, a
  // batch waits kAnswerWait (from its append's start) for the append before the pipeline
  // goes on: most appends land by then and are answered at once; a slow one no longer
  // holds up the load pass and the next batches. An edit arriving ends the wait.
  static constexpr size_t kMaxPendingBatches = 3;
  static constexpr auto kAnswerWait = std::chrono::milliseconds(6);
  bool batches_in_flight() const { return commit_ && !commit_->empty(); }
  void finish_pending(size_t keep) {  // answers landed batches; past `keep`, waits
    if (commit_) commit_->finish(keep);
  }
  void finish_landed();  // finish_pending without waiting, between batches
  void wait_for_answer(Clock::time_point until);
  // After a failed append that carried region changes: an append of the whole region
  // table alone, once the store may be tried again (or, with `now_anyway`, at stop).
  void repair_regions(Clock::time_point now, bool now_anyway = false);
  void restore_from_store();  // constructor: the checkpoints, then the log replayed
  void preload_stored(const std::vector<store::LoggedEdit>& tail);

  // Meshes (world_pipeline_mesh.cpp): `dirty` sorted and deduplicated, each chunk meshed in
  // parallel; publish() gives the changed meshes their versions (`edited_at`: none for a
  // load's meshes).
  std::vector<world::ChunkCoord> remesh_and_publish(std::vector<world::ChunkCoord>& dirty,
                                                    const EditTimes* edited_at = nullptr);
  FreshMeshes remesh(std::vector<world::ChunkCoord>& dirty);
  std::vector<world::ChunkCoord> publish(const std::vector<world::ChunkCoord>& dirty,
                                         FreshMeshes& fresh, const EditTimes* edited_at);
  MeshVersionPtr newest_mesh(world::ChunkCoord c) const;  // a pending batch's, else published

  // Loads and memory (world_pipeline_loads.cpp).
  std::vector<LoadSlice> take_loads(LoadPlan& plan, Clock::time_point now);
  void process_loads(std::vector<LoadSlice>& loads, LoadPlan& plan, Clock::time_point now);
  size_t load_work_allowed(bool edits_waiting);
  void manage_memory(Clock::time_point now);
  size_t accounted_bytes() const;  // resident, and what is on its way
  size_t resident_bytes() const;

  // Level of detail (world_pipeline_lod.cpp): whether the stage may run now (no batch
  // waits for the store), one pass of it, and a durable batch's edits reaching it.
  bool lod_ready(const Inbox::State& in, Clock::time_point now) const;
  void lod_pass(Clock::time_point now);
  void lod_edited(const EditBatch& b, Clock::time_point now);
  void notify_lod(const std::vector<LodKey>& published);  // routed to their owners
  void lod_stats(PipelineStats& s) const;                 // any thread

  // Checkpoints (world_pipeline_checkpoint.cpp).
  void checkpoint_if_due(Clock::time_point now);
  void start_checkpoint(Clock::time_point now);
  uint64_t logged_since_checkpoint() const;  // pending batches' edits included
  void finish_checkpoint(const CheckpointResult& r, Clock::time_point now);
  void final_checkpoint();  // at stop: everything unsaved, waited for

  const PipelineConfig config_;
  const PipelineObserver observer_;
  const world::TerrainGenerator generator_;
  MeshStore meshes_;         // any thread
  Inbox inbox_;              // any thread
  Subscribers subscribers_;  // any thread
  MemoryKeeper memory_;      // pipeline thread, but loads_blocked()
  std::atomic<size_t> other_bytes_{0};
  mutable std::mutex stats_mutex_;  // leaf lock
  PipelineStats stats_;
  BatchCounts batch_counts_;  // of the batch in hand, for the slow-batch log; pipeline thread

  // Pipeline thread only (but each part's any-thread members).
  std::unique_ptr<WorldState> state_;
  std::unique_ptr<StoredChunkReader> reader_;  // with a store
  std::unique_ptr<LodStage> lod_;              // lod_meshes(): any thread
  // Since when the stage had work but a batch waiting for the store held it back; past
  // kLodStarvation the pass waits for the appends.
  std::optional<Clock::time_point> lod_starved_since_;
  static constexpr auto kLodStarvation = std::chrono::milliseconds(250);
  ProtectedRegions regions_;  // regions(): any thread
  // With a store. These three are reset by stop() once thread_ has ended (their threads
  // wake the pipeline).
  std::unique_ptr<Checkpoints> checkpoints_;
  std::unique_ptr<DurableCommit> commit_;
  std::unique_ptr<ViewLoads> loads_;
  std::thread thread_;
};

}  // namespace vox::pipeline
