#include "pipeline/world_pipeline.hpp"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "mesh/marching_cubes.hpp"
#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "world/edit_apply.hpp"
#include "world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;
using world::ChunkCoordHash;
using Clock = std::chrono::steady_clock;

namespace {

struct MeshWorker {
  mesh::PaddedBlock block;
  mesh::MeshScratch scratch;
  proto::CodecScratch codec;
  proto::ZstdCodec zstd;
};

bool same_mesh(const mesh::ChunkMesh& a, const mesh::ChunkMesh& b) {
  return a.indices == b.indices && a.positions == b.positions && a.normals == b.normals &&
         a.materials == b.materials;
}

using CoordSet = std::unordered_set<ChunkCoord, ChunkCoordHash>;
// Summing every loaded chunk's memory after each batch cost ~10 % of the server's CPU
// with 500 players (12,000 chunks): it is refreshed this often instead.
constexpr auto kMemoryScanEvery = std::chrono::milliseconds(500);

}  // namespace

struct WorldPipeline::State {
  explicit State(int threads) : arena(arena_concurrency(threads)) {}

  struct ChunkInfo {
    bool modified = false;
    Clock::time_point last_used;
  };
  world::ChunkMap chunks;
  std::unordered_map<ChunkCoord, ChunkInfo, ChunkCoordHash> info;
  tbb::task_arena arena;
  tbb::enumerable_thread_specific<std::unique_ptr<MeshWorker>> workers{
      [] { return std::make_unique<MeshWorker>(); }};
  uint64_t next_version = 1;
  size_t modified_count = 0;  // chunks with info.modified
  Clock::time_point last_eviction = Clock::now();
  Clock::time_point last_memory_scan{};  // chunk_bytes is a scan of every chunk: throttled

  // Loads (generates) every chunk of `coords` that is missing; parallel over columns so
  // each column's surface heights are computed once.
  size_t ensure_loaded(const std::vector<ChunkCoord>& coords, const world::TerrainGenerator& gen,
                       Clock::time_point now) {
    std::map<std::pair<int32_t, int32_t>, std::vector<int32_t>> columns;
    for (const ChunkCoord& c : coords) {
      auto it = info.find(c);
      if (it != info.end()) {
        it->second.last_used = now;
        continue;
      }
      columns[{c.x, c.z}].push_back(c.y);
    }
    if (columns.empty()) return 0;
    std::vector<std::pair<std::pair<int32_t, int32_t>, std::vector<int32_t>>> work(columns.begin(),
                                                                                   columns.end());
    std::vector<std::vector<world::Chunk>> made(work.size());
    parallel_for_index(arena, work.size(), [&](size_t i) {
      const auto& [xz, ys] = work[i];
      const world::ColumnHeights heights = gen.column(xz.first, xz.second);
      for (int32_t y : ys) made[i].push_back(gen.generate({xz.first, y, xz.second}, heights));
    });
    size_t generated = 0;
    for (size_t i = 0; i < work.size(); ++i) {
      for (size_t k = 0; k < work[i].second.size(); ++k) {
        const ChunkCoord c{work[i].first.first, work[i].second[k], work[i].first.second};
        if (info.count(c)) continue;  // listed twice
        chunks.insert(c, std::move(made[i][k]));
        info[c] = {false, now};
        ++generated;
      }
    }
    return generated;
  }
};

WorldPipeline::WorldPipeline(PipelineConfig config)
    : config_(std::move(config)),
      generator_(config_.seed, config_.terrain),
      state_(std::make_unique<State>(config_.threads)) {
  thread_ = std::thread([this] { run(); });
}

WorldPipeline::~WorldPipeline() { stop(); }

void WorldPipeline::enqueue(Task task) {
  {
    std::lock_guard lock(queue_mutex_);
    if (!stopping_) {
      queue_.push_back(std::move(task));
      queue_cv_.notify_one();
      return;
    }
  }
  std::vector<Task> late;
  late.push_back(std::move(task));
  drain_after_stop(late);  // runs the callback on the caller's thread
}

void WorldPipeline::submit(world::Edit edit, EditCallback done) {
  enqueue(EditTask{std::move(edit), std::move(done)});
}

std::future<EditResult> WorldPipeline::submit(world::Edit edit) {
  auto promise = std::make_shared<std::promise<EditResult>>();
  auto future = promise->get_future();
  submit(std::move(edit), [promise](const EditResult& r) { promise->set_value(r); });
  return future;
}

void WorldPipeline::load(mesh::ChunkBox box, std::function<void()> done) {
  enqueue(LoadTask{box, std::move(done)});
}

std::future<void> WorldPipeline::load(mesh::ChunkBox box) {
  auto promise = std::make_shared<std::promise<void>>();
  auto future = promise->get_future();
  load(box, [promise] { promise->set_value(); });
  return future;
}

void WorldPipeline::inspect(std::function<void(const world::ChunkMap&)> fn) {
  auto finished = std::make_shared<std::promise<void>>();
  auto future = finished->get_future();
  enqueue(InspectTask{std::move(fn), finished});
  future.wait();
}

uint64_t WorldPipeline::subscribe(Subscriber s) {
  std::lock_guard lock(subscribers_mutex_);
  subscribers_.emplace_back(next_subscriber_, std::move(s));
  return next_subscriber_++;
}

void WorldPipeline::unsubscribe(uint64_t id) {
  std::lock_guard lock(subscribers_mutex_);
  std::erase_if(subscribers_, [id](const auto& p) { return p.first == id; });
}

PipelineStats WorldPipeline::stats() const {
  PipelineStats s;
  {
    std::lock_guard lock(stats_mutex_);
    s = stats_;
  }
  s.mesh_count = meshes_.size();
  s.mesh_bytes = meshes_.memory_bytes();
  std::lock_guard lock(queue_mutex_);
  s.queue_depth = queue_.size();
  return s;
}

void WorldPipeline::stop() {
  {
    std::lock_guard lock(queue_mutex_);
    stopping_ = true;
  }
  queue_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void WorldPipeline::run() {
  std::vector<Task> tasks;
  for (;;) {
    bool stopping = false;
    {
      std::unique_lock lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      stopping = stopping_;
      if (!stopping) {
        const size_t n = std::min(queue_.size(), config_.max_batch);
        tasks.assign(std::make_move_iterator(queue_.begin()),
                     std::make_move_iterator(queue_.begin() + static_cast<long>(n)));
        queue_.erase(queue_.begin(), queue_.begin() + static_cast<long>(n));
      } else {
        tasks.assign(std::make_move_iterator(queue_.begin()),
                     std::make_move_iterator(queue_.end()));
        queue_.clear();
      }
    }
    if (stopping) {
      drain_after_stop(tasks);
      return;
    }
    process(tasks);
    tasks.clear();
  }
}

void WorldPipeline::drain_after_stop(std::vector<Task>& tasks) {
  for (Task& t : tasks) {
    if (auto* e = std::get_if<EditTask>(&t)) {
      EditResult r;
      r.reason = world::RefusalReason::kShuttingDown;
      r.message = "shutting down: the world pipeline has stopped";
      if (e->done) e->done(r);
    } else if (auto* l = std::get_if<LoadTask>(&t)) {
      if (l->done) l->done();
    } else if (auto* i = std::get_if<InspectTask>(&t)) {
      if (state_ && thread_.get_id() == std::this_thread::get_id()) i->fn(state_->chunks);
      i->finished->set_value();
    }
  }
}

// Applies one valid edit: loads what it and the meshes it dirties need, changes the
// touched chunks (in parallel), and appends the chunks whose meshes must be rebuilt.
// Returns the number of chunks generated.
size_t WorldPipeline::apply_edit_task(const world::Edit& edit, Clock::time_point now,
                                      std::vector<ChunkCoord>& dirtied) {
  State& st = *state_;
  const world::VoxelBox box = world::touched_box(edit);
  const std::vector<ChunkCoord> touched = world::chunks_overlapping(box);
  // Touched chunks, the neighbours they may dirty, and those neighbours' neighbours.
  const ChunkCoord lo = touched.front().offset(-2, -2, -2), hi = touched.back().offset(2, 2, 2);
  std::vector<ChunkCoord> wanted;
  for (int32_t z = lo.z; z <= hi.z; ++z)
    for (int32_t y = lo.y; y <= hi.y; ++y)
      for (int32_t x = lo.x; x <= hi.x; ++x) wanted.push_back({x, y, z});
  const size_t generated = st.ensure_loaded(wanted, generator_, now);

  std::optional<world::SampleSnapshot> snapshot;
  if (const auto* smooth = std::get_if<world::Smooth>(&edit)) {
    snapshot = world::take_snapshot(st.chunks, world::smooth_read_box(*smooth));
  }
  std::vector<world::ChangedBox> changed(touched.size());
  std::vector<world::Chunk*> targets(touched.size());
  for (size_t i = 0; i < touched.size(); ++i) targets[i] = st.chunks.find(touched[i]);
  const world::SampleSnapshot* snap = snapshot ? &*snapshot : nullptr;
  if (touched.size() == 1) {
    changed[0] = world::apply_edit(edit, touched[0], *targets[0], snap);
  } else {
    parallel_for_index(st.arena, touched.size(), [&](size_t i) {
      changed[i] = world::apply_edit(edit, touched[i], *targets[i], snap);
    });
  }
  for (size_t i = 0; i < touched.size(); ++i) {
    if (!changed[i].changed) continue;
    bool& modified = st.info[touched[i]].modified;
    st.modified_count += modified ? 0 : 1;
    modified = true;
    world::append_dirty_chunks(touched[i], changed[i], dirtied);
  }
  return generated;
}

// Re-meshes every dirty chunk once, in parallel, encodes the meshes that changed and
// publishes them as new versions. Returns the chunks given a new version.
std::vector<ChunkCoord> WorldPipeline::remesh_and_publish(std::vector<ChunkCoord>& dirty) {
  State& st = *state_;
  std::sort(dirty.begin(), dirty.end());
  dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
  std::vector<std::shared_ptr<MeshVersion>> fresh(dirty.size());
  std::vector<MeshVersionPtr> previous(dirty.size());
  for (size_t i = 0; i < dirty.size(); ++i) previous[i] = meshes_.get(dirty[i]);
  parallel_for_index(st.arena, dirty.size(), [&](size_t i) {
    MeshWorker& w = *st.workers.local();
    auto version = std::make_shared<MeshVersion>();
    version->coord = dirty[i];
    mesh::gather_padded_block(st.chunks, dirty[i], w.block);
    mesh::mesh_chunk(w.block, w.scratch, version->mesh);
    if (previous[i] && same_mesh(previous[i]->mesh, version->mesh)) return;
    // Encoded once here, while the mesher's topology is at hand; every client shares it.
    proto::encode_mesh(version->mesh, w.scratch, w.block.cells, w.codec, version->encoding);
    w.zstd.compress(version->encoding, {}, version->full_frame);
    fresh[i] = std::move(version);
  });
  std::vector<ChunkCoord> published;
  for (size_t i = 0; i < dirty.size(); ++i) {
    if (!fresh[i]) continue;
    fresh[i]->version = st.next_version++;
    meshes_.publish(std::move(fresh[i]));
    published.push_back(dirty[i]);
  }
  return published;
}

void WorldPipeline::process(std::vector<Task>& tasks) {
  State& st = *state_;
  const Clock::time_point now = Clock::now();
  PipelineStats delta;
  std::vector<ChunkCoord> dirty;  // may repeat; deduplicated below
  std::vector<std::vector<ChunkCoord>> edit_dirty(tasks.size());
  std::vector<EditResult> results(tasks.size());
  std::vector<ChunkCoord> wanted;

  for (size_t t = 0; t < tasks.size(); ++t) {
    if (auto* load = std::get_if<LoadTask>(&tasks[t])) {
      // The box and a one-chunk margin (the mesher reads the neighbours).
      const mesh::ChunkBox& b = load->box;
      const mesh::ChunkBox outer{b.lo.offset(-1, -1, -1), b.hi.offset(1, 1, 1)};
      wanted.clear();
      for (size_t i = 0; i < outer.count(); ++i) wanted.push_back(outer.at(i));
      delta.chunks_generated += st.ensure_loaded(wanted, generator_, now);
      for (size_t i = 0; i < b.count(); ++i) {
        const ChunkCoord c = b.at(i);
        if (!meshes_.get(c)) dirty.push_back(c);
      }
      continue;
    }
    if (auto* insp = std::get_if<InspectTask>(&tasks[t])) {
      // Sees every edit queued before it applied; the meshes of this batch are not
      // published yet, but densities are final.
      insp->fn(st.chunks);
      insp->finished->set_value();
      continue;
    }
    auto& task = std::get<EditTask>(tasks[t]);
    if (auto refusal = world::validate(task.edit, config_.limits)) {
      results[t].reason = refusal->reason;
      results[t].message = refusal->message;
      ++delta.edits_refused;
      continue;
    }
    results[t].accepted = true;
    ++delta.edits_applied;
    delta.chunks_generated += apply_edit_task(task.edit, now, edit_dirty[t]);
    dirty.insert(dirty.end(), edit_dirty[t].begin(), edit_dirty[t].end());
  }

  const std::vector<ChunkCoord> published = remesh_and_publish(dirty);
  const CoordSet published_set(published.begin(), published.end());
  delta.meshes_published = published.size();

  {
    std::lock_guard lock(stats_mutex_);
    stats_.batches += 1;
    stats_.edits_applied += delta.edits_applied;
    stats_.edits_refused += delta.edits_refused;
    stats_.meshes_published += delta.meshes_published;
    stats_.chunks_generated += delta.chunks_generated;
    stats_.loaded_chunks = st.chunks.size();
    stats_.modified_chunks = st.modified_count;
    if (now - st.last_memory_scan >= kMemoryScanEvery) {
      st.last_memory_scan = now;
      stats_.chunk_bytes = st.chunks.memory_bytes();
    }
  }

  // Results, then subscribers: an edit's result is known once its meshes are published.
  for (size_t t = 0; t < tasks.size(); ++t) {
    if (auto* task = std::get_if<EditTask>(&tasks[t])) {
      auto& r = results[t];
      for (const ChunkCoord& c : edit_dirty[t]) {
        if (published_set.count(c)) r.changed_chunks.push_back(c);
      }
      std::sort(r.changed_chunks.begin(), r.changed_chunks.end());
      r.changed_chunks.erase(std::unique(r.changed_chunks.begin(), r.changed_chunks.end()),
                             r.changed_chunks.end());
      if (task->done) task->done(r);
    } else if (auto* load = std::get_if<LoadTask>(&tasks[t])) {
      if (load->done) load->done();
    }
  }
  if (!published.empty()) {
    std::vector<Subscriber> subscribers;
    {
      std::lock_guard lock(subscribers_mutex_);
      for (const auto& [id, s] : subscribers_) subscribers.push_back(s);
    }
    for (const auto& s : subscribers) s(published);
  }
  if (now - st.last_eviction > config_.evict_after / 4) evict_idle(now);
}

void WorldPipeline::evict_idle(Clock::time_point now) {
  State& st = *state_;
  st.last_eviction = now;
  std::vector<ChunkCoord> victims;
  for (const auto& [c, info] : st.info) {
    if (info.modified || now - info.last_used < config_.evict_after) continue;
    const MeshVersionPtr mesh = meshes_.get(c);
    if (mesh && mesh.use_count() > 2) continue;  // someone besides the store (and us) holds it
    victims.push_back(c);
  }
  for (const ChunkCoord& c : victims) {
    st.chunks.erase(c);
    st.info.erase(c);
    meshes_.erase(c);
  }
  std::lock_guard lock(stats_mutex_);
  stats_.chunks_evicted += victims.size();
  stats_.loaded_chunks = st.chunks.size();
  stats_.chunk_bytes = st.chunks.memory_bytes();
}

}  // namespace vox::pipeline
