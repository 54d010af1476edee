#include "pipeline/world_pipeline.hpp"

#include <spdlog/spdlog.h>
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
// A batch slower than this is logged: every edit queued behind it waited.
constexpr auto kSlowBatch = std::chrono::milliseconds(100);
// A load is split into groups of this many chunks; while edits wait, a batch takes groups
// up to this much work (chunks to generate + chunks to mesh / 4: about 10 ms on 2 cores).
constexpr size_t kLoadGroup = 32;
constexpr size_t kLoadWorkBudget = 64;
constexpr size_t kLoadPassWork = 512;  // a pass while no edit waits (~80 ms cold)

}  // namespace

struct WorldPipeline::State {
  explicit State(int threads) : arena(arena_concurrency(threads)) {}

  struct ChunkInfo {
    bool modified = false;
    bool meshed = false;  // its mesh is in the store (so its neighbours were loaded)
    Clock::time_point last_used;
  };
  world::ChunkMap chunks;
  std::unordered_map<ChunkCoord, ChunkInfo, ChunkCoordHash> info;
  tbb::task_arena arena;
  tbb::enumerable_thread_specific<std::unique_ptr<MeshWorker>> workers{
      [] { return std::make_unique<MeshWorker>(); }};
  uint64_t next_version = 1;
  size_t modified_count = 0;  // chunks with info.modified
  // Surface heights of the columns generated during one process_loads call (its passes
  // share them; cleared after it).
  std::map<std::pair<int32_t, int32_t>, std::shared_ptr<const world::ColumnHeights>> column_heights;
  Clock::time_point last_eviction = Clock::now();

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
    std::vector<std::shared_ptr<const world::ColumnHeights>> heights(work.size());
    for (size_t i = 0; i < work.size(); ++i) {
      if (auto it = column_heights.find(work[i].first); it != column_heights.end())
        heights[i] = it->second;
    }
    parallel_for_index(arena, work.size(), [&](size_t i) {
      const auto& [xz, ys] = work[i];
      if (!heights[i])
        heights[i] = std::make_shared<const world::ColumnHeights>(gen.column(xz.first, xz.second));
      for (int32_t y : ys) made[i].push_back(gen.generate({xz.first, y, xz.second}, *heights[i]));
    });
    for (size_t i = 0; i < work.size(); ++i) column_heights.emplace(work[i].first, heights[i]);
    size_t generated = 0;
    for (size_t i = 0; i < work.size(); ++i) {
      for (size_t k = 0; k < work[i].second.size(); ++k) {
        const ChunkCoord c{work[i].first.first, work[i].second[k], work[i].first.second};
        if (info.count(c)) continue;  // listed twice
        chunks.insert(c, std::move(made[i][k]));
        info[c] = {.last_used = now};
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
      if (std::holds_alternative<EditTask>(task))
        queued_edits_.fetch_add(1, std::memory_order_relaxed);
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
  // Split into groups of chunks, nearest the box's centre first, so that edits can be
  // applied between them and the meshes are published (and streamed) from the centre out;
  // `done` runs once, after the last group.
  std::vector<ChunkCoord> chunks(box.count());
  for (size_t i = 0; i < chunks.size(); ++i) chunks[i] = box.at(i);
  const int64_t cx = (int64_t{box.lo.x} + box.hi.x), cy = (int64_t{box.lo.y} + box.hi.y),
                cz = (int64_t{box.lo.z} + box.hi.z);  // twice the centre
  auto distance2 = [&](const ChunkCoord& c) {
    const int64_t dx = 2 * int64_t{c.x} - cx, dy = 2 * int64_t{c.y} - cy,
                  dz = 2 * int64_t{c.z} - cz;
    return dx * dx + dy * dy + dz * dz;
  };
  // Ties by coordinate: a total order, so std::sort is deterministic (std::stable_sort's
  // temporary buffer trips ASan's new/free check with GCC 12's libstdc++).
  std::sort(chunks.begin(), chunks.end(), [&](const ChunkCoord& a, const ChunkCoord& b) {
    const int64_t da = distance2(a), db = distance2(b);
    return da != db ? da < db : a < b;
  });
  const size_t groups = std::max<size_t>(1, (chunks.size() + kLoadGroup - 1) / kLoadGroup);
  auto remaining = std::make_shared<std::atomic<size_t>>(groups);
  auto shared_done = std::make_shared<std::function<void()>>(std::move(done));
  for (size_t g = 0; g < groups; ++g) {
    const auto from =
        chunks.begin() + static_cast<std::ptrdiff_t>(std::min(chunks.size(), g * kLoadGroup));
    const auto to =
        chunks.begin() + static_cast<std::ptrdiff_t>(std::min(chunks.size(), (g + 1) * kLoadGroup));
    enqueue(LoadTask{std::vector<ChunkCoord>(from, to), [remaining, shared_done] {
                       if (remaining->fetch_sub(1) == 1 && *shared_done) (*shared_done)();
                     }});
  }
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
        queued_edits_.fetch_sub(
            static_cast<size_t>(
                std::count_if(tasks.begin(), tasks.end(),
                              [](const Task& t) { return std::holds_alternative<EditTask>(t); })),
            std::memory_order_relaxed);
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
  std::vector<char> was_uniform(touched.size());
  for (size_t i = 0; i < touched.size(); ++i) {
    targets[i] = st.chunks.find(touched[i]);
    was_uniform[i] = targets[i]->is_uniform();
  }
  const world::SampleSnapshot* snap = snapshot ? &*snapshot : nullptr;
  if (touched.size() == 1) {
    changed[0] = world::apply_edit(edit, touched[0], *targets[0], snap);
  } else {
    parallel_for_index(st.arena, touched.size(), [&](size_t i) {
      changed[i] = world::apply_edit(edit, touched[i], *targets[i], snap);
    });
  }
  for (size_t i = 0; i < touched.size(); ++i) {
    st.chunks.note_changed(was_uniform[i] != 0, *targets[i]);
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
  for (const ChunkCoord& c : dirty) {
    if (auto it = st.info.find(c); it != st.info.end()) it->second.meshed = true;
  }
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
  PipelineStats batch;  // the whole batch's counts, for the slow-batch log
  process_edits(tasks, now, batch);
  process_loads(tasks, now, batch);
  {
    std::lock_guard lock(stats_mutex_);
    stats_.batches += 1;
  }
  if (now - st.last_eviction > config_.evict_after / 4) evict_idle(now);
  const auto took = Clock::now() - now;
  if (took > kSlowBatch) {
    spdlog::warn(
        "pipeline: a batch took {} ms ({} edits, {} tasks, {} chunks generated, {} meshes "
        "published)",
        std::chrono::duration_cast<std::chrono::milliseconds>(took).count(), batch.edits_applied,
        tasks.size(), batch.chunks_generated, batch.meshes_published);
  }
}

// Edits and inspections, in arrival order; loads are left for process_loads.
void WorldPipeline::process_edits(std::vector<Task>& tasks, Clock::time_point now,
                                  PipelineStats& batch) {
  PipelineStats delta;
  std::vector<ChunkCoord> dirty;  // may repeat; deduplicated below
  std::vector<std::vector<ChunkCoord>> edit_dirty(tasks.size());
  std::vector<EditResult> results(tasks.size());
  bool any_edit = false;
  for (size_t t = 0; t < tasks.size(); ++t) {
    if (auto* insp = std::get_if<InspectTask>(&tasks[t])) {
      // Sees every edit queued before it applied; the meshes of this batch are not
      // published yet, but densities are final.
      insp->fn(state_->chunks);
      insp->finished->set_value();
      continue;
    }
    auto* task = std::get_if<EditTask>(&tasks[t]);
    if (!task) continue;
    any_edit = true;
    if (auto refusal = world::validate(task->edit, config_.limits)) {
      results[t].reason = refusal->reason;
      results[t].message = refusal->message;
      ++delta.edits_refused;
      continue;
    }
    results[t].accepted = true;
    ++delta.edits_applied;
    delta.chunks_generated += apply_edit_task(task->edit, now, edit_dirty[t]);
    dirty.insert(dirty.end(), edit_dirty[t].begin(), edit_dirty[t].end());
  }
  if (!any_edit) return;
  const std::vector<ChunkCoord> published = remesh_and_publish(dirty);
  const CoordSet published_set(published.begin(), published.end());
  delta.meshes_published += published.size();
  commit_stats(delta, batch);  // before the results: whoever waits on one sees its counts
  // Results, then subscribers: an edit's result is known once its meshes are published.
  for (size_t t = 0; t < tasks.size(); ++t) {
    auto* task = std::get_if<EditTask>(&tasks[t]);
    if (!task) continue;
    auto& r = results[t];
    for (const ChunkCoord& c : edit_dirty[t]) {
      if (published_set.count(c)) r.changed_chunks.push_back(c);
    }
    std::sort(r.changed_chunks.begin(), r.changed_chunks.end());
    r.changed_chunks.erase(std::unique(r.changed_chunks.begin(), r.changed_chunks.end()),
                           r.changed_chunks.end());
    if (task->done) task->done(r);
  }
  notify_subscribers(published);
}

// Loads (each a group of chunks, see load()), in order, in passes: a pass takes groups
// up to a work budget, generates their missing chunks in one parallel pass (each column's
// heights once), meshes and publishes them. The budget is small while edits are queued,
// and once a pass ends with edits queued the rest goes back to the front of the queue:
// edits are applied before it and never wait behind a whole world of terrain generation.
void WorldPipeline::process_loads(std::vector<Task>& tasks, Clock::time_point now,
                                  PipelineStats& batch) {
  std::vector<LoadTask*> loads;
  for (Task& task : tasks) {
    if (auto* load = std::get_if<LoadTask>(&task)) loads.push_back(load);
  }
  size_t next = 0;
  struct ClearColumns {
    State& st;
    ~ClearColumns() { st.column_heights.clear(); }
  } clear_columns{*state_};
  while (next < loads.size()) {
    const size_t budget =
        queued_edits_.load(std::memory_order_relaxed) > 0 ? kLoadWorkBudget : kLoadPassWork;
    next = load_pass(loads, next, budget, now, batch);
    if (next < loads.size() && queued_edits_.load(std::memory_order_relaxed) > 0) break;
  }
  if (next == loads.size()) return;
  std::vector<Task> later;
  for (size_t i = next; i < loads.size(); ++i) later.emplace_back(std::move(*loads[i]));
  std::lock_guard lock(queue_mutex_);
  queue_.insert(queue_.begin(), std::make_move_iterator(later.begin()),
                std::make_move_iterator(later.end()));
}

// One pass of process_loads over loads[from..]: returns where the next pass starts.
size_t WorldPipeline::load_pass(const std::vector<LoadTask*>& loads, size_t from, size_t budget,
                                Clock::time_point now, PipelineStats& batch) {
  PipelineStats delta;
  State& st = *state_;
  std::vector<ChunkCoord> dirty;
  CoordSet wanted;  // chunks to generate
  size_t end = from;
  // Work: chunks to generate, plus a quarter of the chunks to mesh.
  for (; end < loads.size() && (end == from || wanted.size() + dirty.size() / 4 < budget); ++end) {
    // The chunks and a one-chunk margin (the mesher reads the neighbours); a chunk meshed
    // already (most of a view that moved by one chunk) is only marked as used.
    for (const ChunkCoord& c : loads[end]->chunks) {
      if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
        it->second.last_used = now;
        continue;
      }
      dirty.push_back(c);
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const ChunkCoord n = c.offset(dx, dy, dz);
            if (auto it = st.info.find(n); it != st.info.end()) {
              it->second.last_used = now;
            } else {
              wanted.insert(n);
            }
          }
    }
  }
  delta.chunks_generated +=
      st.ensure_loaded(std::vector<ChunkCoord>(wanted.begin(), wanted.end()), generator_, now);
  const std::vector<ChunkCoord> published = remesh_and_publish(dirty);
  delta.meshes_published += published.size();
  commit_stats(delta, batch);
  for (size_t i = from; i < end; ++i) {
    if (loads[i]->done) loads[i]->done();
  }
  notify_subscribers(published);
  return end;
}

// Adds the counts of `delta` to the stats and to `batch` (the whole batch's, for the
// slow-batch log); refreshes the loaded-chunk figures.
void WorldPipeline::commit_stats(const PipelineStats& delta, PipelineStats& batch) {
  State& st = *state_;
  batch.edits_applied += delta.edits_applied;
  batch.edits_refused += delta.edits_refused;
  batch.meshes_published += delta.meshes_published;
  batch.chunks_generated += delta.chunks_generated;
  std::lock_guard lock(stats_mutex_);
  stats_.edits_applied += delta.edits_applied;
  stats_.edits_refused += delta.edits_refused;
  stats_.meshes_published += delta.meshes_published;
  stats_.chunks_generated += delta.chunks_generated;
  stats_.loaded_chunks = st.chunks.size();
  stats_.modified_chunks = st.modified_count;
  stats_.chunk_bytes = st.chunks.memory_bytes();
}

void WorldPipeline::notify_subscribers(const std::vector<ChunkCoord>& published) {
  if (published.empty()) return;
  std::vector<Subscriber> subscribers;
  {
    std::lock_guard lock(subscribers_mutex_);
    for (const auto& [id, s] : subscribers_) subscribers.push_back(s);
  }
  for (const auto& s : subscribers) s(published);
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
