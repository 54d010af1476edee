// The single logical writer of chunk densities: a batch loop over parts. Edits, view loads
// and inspections arrive from any thread through the Inbox; a BatchScheduler decides what
// each batch holds (every queued edit, then loads round robin over their owners within a
// work budget). One pipeline thread applies a batch (apply_edits), re-meshes the dirty
// chunks in parallel (remesh.hpp), has the batch made durable (DurableCommit), publishes
// each changed mesh as a new immutable version, then reports results and notifies
// subscribers. Readers use meshes() and never block it. Between batches the parts take
// their turns: loads (ViewLoads), the level-of-detail stage, eviction (MemoryKeeper),
// checkpoints. The rules between the parts are the loop's own lines (world_pipeline.cpp).
#pragma once

#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_set>
#include <vector>

#include "server/mesh/region_mesher.hpp"
#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/durable_commit.hpp"
#include "server/pipeline/edit_ids.hpp"
#include "server/pipeline/edit_step.hpp"
#include "server/pipeline/inbox.hpp"
#include "server/pipeline/lod_stage.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/pipeline_config.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/query_pass.hpp"
#include "server/pipeline/rollback_slices.hpp"
#include "server/pipeline/rollbacks.hpp"
#include "server/pipeline/stats_book.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/subscribers.hpp"
#include "server/pipeline/view_loads.hpp"

namespace vox::pipeline {

struct WorldState;

class WorldPipeline {
 public:
  using EditCallback = std::function<void(const EditResult&)>;
  using LodPublication = pipeline::LodPublication;
  using LodKeys = pipeline::LodKeys;

  explicit WorldPipeline(PipelineConfig config, PipelineObserver observer = {});
  ~WorldPipeline();  // stop()
  WorldPipeline(const WorldPipeline&) = delete;
  WorldPipeline& operator=(const WorldPipeline&) = delete;

  // Any thread. `done` runs on the pipeline thread once the edit's meshes are published
  // (or it was refused); it must not block. Every queued edit is in the next batch.
  // `owner` (a session id; 0 for none) bounds the terrain its edits may make the pipeline
  // generate in one batch. `author`: the player id the edit is logged under;
  // `bypass_regions`: an admin's edit, which protected regions do not hold back.
  void submit(world::Edit edit, EditCallback done, LoadOwner owner = 0, std::string author = {},
              bool bypass_regions = false) {
    submit(
        EditTask{std::move(edit), std::move(done), owner, {}, std::move(author), bypass_regions});
  }
  std::future<EditResult> submit(world::Edit edit);
  // Any thread: the world's id of a player's edit carrying `client_id` (0: none).
  uint64_t edit_id_of(std::string_view player, uint64_t client_id) const {
    return EditIds::of_player(config_.edit_id_key, player, client_id);
  }
  // Any thread: a task made whole by the caller (a cluster node's forwarded parts); its
  // `submitted` time is set here.
  void submit(EditTask task) {
    task.submitted = std::chrono::steady_clock::now();
    enqueue(std::move(task));
  }
  // Any thread. Adds or removes a protected region in order with the edits around it;
  // `task.done` runs on the pipeline thread once the change is durable (or refused).
  void change_regions(RegionTask task);
  // Any thread: a rollback (pipeline/rollbacks.hpp), or refused at once without a
  // history store (in memory, a cluster node).
  void rollback(Rollbacks::Job job);
  // Any thread: a rollback's step, in order with the edits (Rollbacks).
  void submit_rollback(RollbackTask task) { enqueue(std::move(task)); }
  // Any thread: a question about the samples, answered in order with the edits.
  void query(QueryTask task) { enqueue(std::move(task)); }
  // Any thread: the protected regions in force, as of the last durable change.
  std::shared_ptr<const std::vector<world::Region>> regions() const { return regions_.published(); }
  // Any thread. Generates and meshes what the box misses; `done` runs on the pipeline
  // thread once every chunk of it has a published mesh.
  void load(mesh::ChunkBox box, std::function<void()> done);
  std::future<void> load(mesh::ChunkBox box);
  // Any thread. The view of `owner` (a session id, below 2^63) becomes the ball of
  // `radius` chunks around `center`: its queued loads are replaced by the new view's
  // missing chunks, nearest first. `budget_group`: the owner's address (0: none), for the
  // per-address load budget. `keep`: of the ball, only the chunks it is true for (a
  // level-of-detail layout's level 0); the whole ball stays safe from eviction.
  void set_view(LoadOwner owner, world::ChunkCoord center, int radius, uint64_t budget_group = 0,
                const std::function<bool(world::ChunkCoord)>& keep = {});
  // Any thread: drops the owner's queued loads and its LOD view (its session closed).
  void drop_view(LoadOwner owner);
  // Any thread. The level-of-detail meshes (levels >= 1, with their seams) `owner`'s
  // layout needs, nearest first, replacing its previous ones; each new version reaches
  // the LOD subscribers whose layouts want it (subscribers.hpp).
  void set_lod_view(LoadOwner owner, std::vector<LodKey> keys);
  // Runs fn on the pipeline thread between batches, and waits for it (tests, persistence).
  void inspect(std::function<void(const world::ChunkMap&)> fn);

  const MeshStore& meshes() const { return meshes_; }                // any thread
  const LodMeshStore& lod_meshes() const { return lod_->meshes(); }  // any thread
  // Any thread. Subscribers run on the pipeline thread after each batch with the chunks
  // (or LOD keys) that got a new version; they must not block (post to your executor).
  uint64_t subscribe(Subscribers::Subscriber s) { return subscribers_.subscribe(std::move(s)); }
  uint64_t subscribe_lod(Subscribers::LodSubscriber s) {
    return subscribers_.subscribe_lod(std::move(s));
  }
  void unsubscribe(uint64_t id) { subscribers_.unsubscribe(id); }
  PipelineStats stats() const;  // any thread
  // Any thread: bytes held outside the pipeline (sessions' state), in the memory budget.
  void set_session_bytes(size_t bytes) { memory_.set_session_bytes(bytes); }
  const PipelineConfig& config() const { return config_; }
  // Finishes the batch in flight, refuses queued edits (kShuttingDown), runs queued load
  // callbacks, checkpoints every unsaved chunk (with a store), joins the thread. Idempotent.
  void stop();

  // Batches in flight (applied, their appends not yet landed) are at most this many:
  // past it, the pipeline waits for the oldest. After re-meshing, a batch waits
  // kAnswerWait (from its append's start) for its append: most land by then and are
  // answered at once; a slow one no longer holds up the next batches. An edit ends it.
  static constexpr size_t kMaxPendingBatches = 3;
  static constexpr auto kAnswerWait = std::chrono::milliseconds(6);

 private:
  // Pipeline thread only: the batch loop and the rules between the parts.
  void run();
  bool batch_ready(Inbox::State& in);                                 // under the inbox's lock
  std::chrono::milliseconds idle_wait(const Inbox::State& in) const;  // likewise
  void take_view_updates(Inbox::State& in);                           // likewise
  void between_batches(Clock::time_point now);
  void edit_pass(std::vector<OrderedTask>& tasks, Clock::time_point now);
  void answer(EditBatch& b, bool durable);  // publish and accept, or refuse what it accepted
  void wait_for_answer(Clock::time_point until);
  void finish_landed();  // answers the batches whose appends landed, without waiting
  void drain_commits();  // answers every batch in flight, waiting for their appends
  void repair_regions(Clock::time_point now, bool now_anyway = false);
  void zone_regions_turn(Clock::time_point now, bool anyway);
  size_t load_pass(Clock::time_point now);  // the chunks it planned to mesh
  void lod_pass(Clock::time_point now);
  void keep_memory(Clock::time_point now);
  void checkpoints_turn(Clock::time_point now);
  void record(const CheckpointResult& r);
  void count(const BatchCounts& delta);
  size_t resident_bytes() const;  // chunks, meshes, LOD meshes, sessions, the unaccounted heap
  size_t on_its_way_bytes() const;
  size_t load_work_allowed(bool edits_waiting) const;
  EditWorld edit_world();  // what apply_edit_step reads and writes
  void drain_after_stop();
  void enqueue(OrderedTask task);

  const PipelineConfig config_;
  const PipelineObserver observer_;
  const world::TerrainGenerator generator_;
  MeshStore meshes_;         // any thread
  Inbox inbox_;              // any thread
  Subscribers subscribers_;  // any thread
  MemoryKeeper memory_;      // pipeline thread, but loads_blocked() and other bytes
  StatsBook stats_;          // stats(): any thread
  // Pipeline thread only (but each part's any-thread members).
  std::unique_ptr<WorldState> state_;
  std::unique_ptr<StoredChunkReader> reader_;  // with a store
  std::unique_ptr<LodStage> lod_;              // lod_meshes(): any thread
  // The last LOD pass put off every mesh it took, for edits not durable yet: no pass
  // before an append lands (batch_ready).
  bool lod_blocked_ = false;
  ProtectedRegions regions_;  // regions(): any thread
  // With a store; reset by stop() once thread_ has ended (their threads wake the pipeline).
  std::unique_ptr<Checkpoints> checkpoints_;
  // Pipeline thread: a single node's applied edit ids (null for a cluster node: its
  // ZoneTable keeps them per zone).
  const std::unique_ptr<EditIds> edit_ids_ = config_.zones ? nullptr : std::make_unique<EditIds>();
  std::unique_ptr<DurableCommit> commit_;
  RollbackSlices rollback_slices_;  // the chunks rollbacks freeze, the checkpoint hold
  QueryBudget query_budget_;        // what all queries may take of the thread
  // Held by a rollback from its plan until its record is logged, and tried by the
  // checkpoint writer before it moves the history's base (else it waits for the next).
  std::mutex history_mutex_;
  std::unique_ptr<ViewLoads> loads_;
  std::thread thread_;
  std::unique_ptr<Rollbacks> rollbacks_;  // with a history store; stopped first
};

}  // namespace vox::pipeline
