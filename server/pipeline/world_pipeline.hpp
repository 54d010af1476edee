// The single logical writer of chunk densities. Edits and region loads arrive on a
// thread-safe queue from any thread; one pipeline thread takes everything queued as a
// batch and, in arrival order, applies it (fanning out over chunks with TBB), re-meshes
// the dirty chunks in parallel, publishes each changed mesh as a new immutable version,
// then reports results and notifies subscribers. Readers use meshes() and never block it.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <variant>
#include <vector>

#include "mesh/region_mesher.hpp"
#include "pipeline/mesh_store.hpp"
#include "world/edit.hpp"
#include "world/terrain_generator.hpp"

namespace vox::pipeline {

struct PipelineConfig {
  uint64_t seed = 1;
  world::TerrainParams terrain;
  int threads = 0;  // worker threads for apply/generate/mesh, 0 = all cores
  world::EditLimits limits;
  size_t max_batch = 4096;  // queued items taken per batch
  // Unmodified chunks unused this long (and whose mesh no one else holds) are dropped;
  // they regenerate from the seed. Modified chunks stay.
  std::chrono::milliseconds evict_after{std::chrono::minutes(2)};
};

struct EditResult {
  bool accepted = false;
  world::RefusalReason reason = world::RefusalReason::kNone;
  std::string message;                            // why it was refused
  std::vector<world::ChunkCoord> changed_chunks;  // chunks given a new mesh version
};

struct PipelineStats {
  uint64_t batches = 0, edits_applied = 0, edits_refused = 0, meshes_published = 0,
           chunks_generated = 0, chunks_evicted = 0;
  size_t loaded_chunks = 0, modified_chunks = 0, chunk_bytes = 0, mesh_count = 0, mesh_bytes = 0;
  size_t queue_depth = 0;
};

class WorldPipeline {
 public:
  using EditCallback = std::function<void(const EditResult&)>;
  using Subscriber = std::function<void(const std::vector<world::ChunkCoord>&)>;

  explicit WorldPipeline(PipelineConfig config);
  ~WorldPipeline();  // stop()
  WorldPipeline(const WorldPipeline&) = delete;
  WorldPipeline& operator=(const WorldPipeline&) = delete;

  // Any thread. `done` runs on the pipeline thread once the edit's meshes are published
  // (or it was refused); it must not block.
  void submit(world::Edit edit, EditCallback done);
  std::future<EditResult> submit(world::Edit edit);
  // Any thread. Generates and meshes whatever of the box is missing; `done` runs on the
  // pipeline thread once every chunk of the box has a published mesh.
  void load(mesh::ChunkBox box, std::function<void()> done);
  std::future<void> load(mesh::ChunkBox box);
  // Runs fn on the pipeline thread between batches, and waits for it (tests, persistence).
  void inspect(std::function<void(const world::ChunkMap&)> fn);

  const MeshStore& meshes() const { return meshes_; }  // any thread
  // Subscribers run on the pipeline thread after each batch with the chunks that got a
  // new version; they must not block (post to your own executor).
  uint64_t subscribe(Subscriber s);  // any thread
  void unsubscribe(uint64_t id);     // any thread
  PipelineStats stats() const;       // any thread
  const PipelineConfig& config() const { return config_; }
  // Finishes the batch in flight, refuses queued edits (kShuttingDown), runs queued load
  // callbacks, joins the thread. Idempotent.
  void stop();

 private:
  struct EditTask {
    world::Edit edit;
    EditCallback done;
  };
  struct LoadTask {
    std::vector<world::ChunkCoord> chunks;  // a part of a loaded box
    std::function<void()> done;
  };
  struct InspectTask {
    std::function<void(const world::ChunkMap&)> fn;
    std::shared_ptr<std::promise<void>> finished;
  };
  using Task = std::variant<EditTask, LoadTask, InspectTask>;

  void enqueue(Task task);
  void run();
  void process(std::vector<Task>& tasks);
  void process_edits(std::vector<Task>& tasks, std::chrono::steady_clock::time_point now,
                     PipelineStats& batch);
  void process_loads(std::vector<Task>& tasks, std::chrono::steady_clock::time_point now,
                     PipelineStats& batch);
  size_t load_pass(const std::vector<LoadTask*>& loads, size_t from, size_t budget,
                   std::chrono::steady_clock::time_point now, PipelineStats& batch);
  void commit_stats(const PipelineStats& delta, PipelineStats& batch);
  void notify_subscribers(const std::vector<world::ChunkCoord>& published);
  size_t apply_edit_task(const world::Edit& edit, std::chrono::steady_clock::time_point now,
                         std::vector<world::ChunkCoord>& dirtied);
  std::vector<world::ChunkCoord> remesh_and_publish(std::vector<world::ChunkCoord>& dirty);
  void drain_after_stop(std::vector<Task>& tasks);
  void evict_idle(std::chrono::steady_clock::time_point now);

  const PipelineConfig config_;
  const world::TerrainGenerator generator_;
  MeshStore meshes_;

  mutable std::mutex queue_mutex_;  // leaf lock, guards queue_ and stopping_
  std::condition_variable queue_cv_;
  std::deque<Task> queue_;
  bool stopping_ = false;
  std::atomic<size_t> queued_edits_{0};  // EditTasks in queue_ (read without the lock)

  mutable std::mutex subscribers_mutex_;  // leaf lock; callbacks run on a copy, outside it
  std::vector<std::pair<uint64_t, Subscriber>> subscribers_;
  uint64_t next_subscriber_ = 1;

  mutable std::mutex stats_mutex_;  // leaf lock
  PipelineStats stats_;

  struct State;  // pipeline-thread-only state (chunk map, workers, ...)
  std::unique_ptr<State> state_;
  std::thread thread_;
};

}  // namespace vox::pipeline
