#include "server/pipeline/world_pipeline.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/pipeline/edit_pass.hpp"
#include "server/pipeline/heap_stats.hpp"
#include "server/pipeline/remesh.hpp"
#include "server/pipeline/world_restore.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/pipeline/zone_records.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/parallel.hpp"
#include "server/world/thread_name.hpp"

namespace vox::pipeline {

using world::ChunkCoord;
using world::ChunkCoordHash;

namespace {

// A batch slower than this is logged: every edit queued behind it waited.
constexpr auto kSlowBatch = std::chrono::milliseconds(100);
// Chunks an owner gets per round-robin turn.
constexpr size_t kLoadGroup = 32;

}  // namespace

WorldPipeline::WorldPipeline(PipelineConfig config, PipelineObserver observer)
    : config_(std::move(config)),
      observer_(std::move(observer)),
      generator_(config_.seed, config_.terrain),
      inbox_(BatchScheduler(kLoadGroup, config_.load_work_per_owner, config_.load_burst_per_owner,
                            config_.load_work_per_address, config_.load_burst_per_address)),
      memory_(MemoryBudget(config_.max_memory), config_.evict_after, config_.evict_min_age,
              Clock::now()),
      state_(std::make_unique<WorldState>(config_.threads)),
      // A read waits for the appends in flight on their connection (not a cluster node's).
      reader_(config_.store ? std::make_unique<StoredChunkReader>(
                                  *config_.store, config_.store_retry,
                                  config_.zones ? std::function<void()>()
                                                : [this] { commit_->wait_for_appends(); })
                            : nullptr),
      lod_(std::make_unique<LodStage>(generator_, *state_, config_.lod, reader_.get())),
      regions_(config_.limits) {
  if (config_.zones) config_.zones->set_wake([this] { inbox_.poke(); });
  if (config_.store) {
    state_->read_stored = [this](ChunkCoord c) { return reader_->read(c); };
    checkpoints_ = std::make_unique<Checkpoints>(
        config_.checkpoint_store ? *config_.checkpoint_store : *config_.store,
        config_.checkpoint_store != nullptr, config_.checkpoint, config_.history,
        [this] { inbox_.poke(); }, Clock::now(), config_.zones ? nullptr : &generator_,
        &history_mutex_);
    if (config_.zones) {  // a cluster node: only the zones it holds, evicted while held
      checkpoints_->set_scope([this](uint64_t s) { return config_.zones->checkpoint_scope(s); });
      state_->may_evict_modified = [this](ChunkCoord c) { return config_.zones->may_evict(c); };
    }
    commit_ = std::make_unique<DurableCommit>(
        *config_.store, config_.store_retry, [this] { inbox_.append_landed(); },
        DurableCommit::Hooks{.answer = [this](EditBatch& b, bool durable) { answer(b, durable); },
                             .undo =
                                 [this](EditBatch& b) {
                                   undo_edits(*state_, checkpoints_.get(), b.undo);
                                   regions_.undo(b.regions);
                                 },
                             .committed =
                                 [this](const AppendOutcome& out, double waited) {
                                   if (observer_.commit && out.first)
                                     observer_.commit(out.seconds, out.edits, out.error.empty());
                                   if (observer_.commit_wait) observer_.commit_wait(waited);
                                 }});
    // Before the pipeline's thread: may throw StoreError.
    EditWorld world = edit_world();
    const RestoredWorld restored = restore_world(*config_.store, world, regions_, *reader_);
    commit_->restore(restored.next_seq);
    if (checkpoints_) checkpoints_->logged(restored.replayed);
    stats_.update([&](PipelineStats& s) {
      StatsBook::residency(s, *state_);
      s.unsaved_chunks = checkpoints_ ? checkpoints_->unsaved_chunks() : 0;
      s.checkpoint_seq = restored.info.checkpoint_seq;
    });
  }
  const int generate_threads =
      config_.generate_threads >= 0
          ? config_.generate_threads
          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  loads_ =
      std::make_unique<ViewLoads>(generator_, *state_, reader_.get(), generate_threads,
                                  config_.max_generating, [this] { inbox_.generated_ready(); });
  lod_->learn_modified();  // what the restore loaded or replayed
  thread_ = named_thread("vox-pipeline", [this] { run(); });
  if (config_.history_store && !config_.zones)
    rollbacks_ = std::make_unique<Rollbacks>(
        *this, *config_.history_store, generator_, config_.max_rollback_chunks, history_mutex_,
        config_.history.keep_all || config_.history.window.count() > 0);
}

WorldPipeline::~WorldPipeline() { stop(); }

void WorldPipeline::enqueue(OrderedTask task) {
  if (!inbox_.add(task)) refuse_stopped(task, true);  // answered on the caller's thread
}

void WorldPipeline::change_regions(RegionTask task) { enqueue(std::move(task)); }

void WorldPipeline::rollback(Rollbacks::Job job) {
  if (rollbacks_) return rollbacks_->submit(std::move(job));
  RollbackReport r;
  r.status = RollbackReport::Status::kRefused;
  r.message = config_.zones ? "rollbacks are not available on a cluster world yet"
                            : "rollbacks need a durable world (not --in-memory)";
  if (job.done) job.done(r);
}

std::future<EditResult> WorldPipeline::submit(world::Edit edit) {
  auto promise = std::make_shared<std::promise<EditResult>>();
  auto future = promise->get_future();
  submit(std::move(edit), [promise](const EditResult& r) { promise->set_value(r); });
  return future;
}

void WorldPipeline::load(mesh::ChunkBox box, std::function<void()> done) {
  if (!inbox_.add_load(box_nearest_first(box.lo, box.hi), done) && done) done();
}

std::future<void> WorldPipeline::load(mesh::ChunkBox box) {
  auto promise = std::make_shared<std::promise<void>>();
  auto future = promise->get_future();
  load(box, [promise] { promise->set_value(); });
  return future;
}

void WorldPipeline::set_view(LoadOwner owner, ChunkCoord center, int radius, uint64_t budget_group,
                             const std::function<bool(ChunkCoord)>& keep) {
  std::vector<ChunkCoord> chunks = ball_nearest_first(center, radius);  // outside the lock
  if (keep) std::erase_if(chunks, [&](ChunkCoord c) { return !keep(c); });
  if (auto replaced = inbox_.set_view(owner, center, radius, std::move(chunks), budget_group))
    replaced();
}

void WorldPipeline::drop_view(LoadOwner owner) {
  if (auto dropped = inbox_.drop_view(owner)) dropped();
}

void WorldPipeline::set_lod_view(LoadOwner owner, std::vector<LodKey> keys) {
  inbox_.set_lod_view(owner, std::move(keys));
}

void WorldPipeline::inspect(std::function<void(const world::ChunkMap&)> fn) {
  auto finished = std::make_shared<std::promise<void>>();
  auto future = finished->get_future();
  enqueue(InspectTask{[this, fn = std::move(fn), finished](bool cancelled) {
    if (!cancelled) fn(state_->chunks);
    finished->set_value();
  }});
  future.wait();
}

PipelineStats WorldPipeline::stats() const {
  PipelineStats s = stats_.snapshot();
  s.mesh_count = meshes_.size();
  s.mesh_bytes = meshes_.memory_bytes();
  s.lod_mesh_count = lod_->meshes().size();
  s.lod_mesh_bytes = lod_->memory_bytes();
  for (int level = 0; level < config_.lod.levels && level < LodStage::kCountedLevels; ++level) {
    s.lod_meshed.push_back(lod_->meshed(level));
    s.lod_remeshed.push_back(lod_->remeshed(level));
    s.lod_published.push_back(lod_->published(level));
  }
  s.session_bytes = memory_.session_bytes();
  s.unaccounted_bytes = memory_.unaccounted_bytes();
  s.accounted_bytes = s.chunk_bytes + s.mesh_bytes + s.lod_mesh_bytes + memory_.other_bytes();
  s.loads_blocked = memory_.loads_blocked();
  const Inbox::Counts queued = inbox_.counts();
  s.queued_edits = queued.edits;
  s.queued_load_chunks = queued.load_chunks;
  s.load_owners = queued.load_owners;
  return s;
}

void WorldPipeline::stop() {
  if (rollbacks_) rollbacks_->stop();  // while the pipeline still answers its tasks
  inbox_.stop();
  if (thread_.joinable()) thread_.join();
  checkpoints_.reset();  // after the final checkpoint
  commit_.reset();       // idle: every batch was answered before thread_ ended
  loads_.reset();
}

// ---- The batch loop and the rules between the parts. Pipeline thread only. ----

// Under the inbox's lock. Loads whose pass the memory budget cuts to nothing while terrain
// is on its way wait for it (generated_ready), not in a busy loop.
bool WorldPipeline::batch_ready(Inbox::State& in) {
  const Clock::time_point now = Clock::now();
  // After a failed read of a stored chunk, a pass now and then tries it again.
  const bool retry_reads = loads_->waiting_for_store() && !reader_->backing_off(now);
  // While a batch waits for the store, the chunk map may show edits that are not durable:
  // the LOD stage puts off the meshes that read them (lod_pass), and after a pass that put
  // off every mesh it took, it waits for an append to land (which wakes us).
  const bool in_flight = commit_ && !commit_->empty();
  const bool lod = !(in_flight && lod_blocked_) && (!in.lod_updates.empty() || lod_->has_work(now));
  return in.scheduler.has_ordered() || in.generated_ready || retry_reads ||
         (in.scheduler.has_loads() && !memory_.loads_blocked() &&
          in.scheduler.has_ready_loads(now) && load_work_allowed(false) > 0) ||
         lod;
}

// Under the inbox's lock: how long the idle pipeline may sleep (a wake-up ends it sooner).
std::chrono::milliseconds WorldPipeline::idle_wait(const Inbox::State& in) const {
  using std::chrono::milliseconds;
  milliseconds wait = memory_.next_look(in.scheduler.has_loads());
  // Unsaved chunks: their checkpoint (a finished one wakes us).
  if (checkpoints_ && checkpoints_->has_unsaved()) wait = std::min(wait, checkpoints_->interval());
  // A chunk not read back, a region table in doubt, a zone's log unread: try again then.
  if (loads_->waiting_for_store() || regions_.doubtful() ||
      (config_.zones && (config_.zones->records_waiting() || config_.zones->regions_changed())))
    wait = std::min(wait, std::chrono::duration_cast<milliseconds>(config_.store_retry));
  // A coarse chunk's re-mesh falls due (while a pass put everything off for edits not
  // durable yet, an append's landing wakes us).
  if (const auto due = lod_->next_due(); due && !(commit_ && !commit_->empty() && lod_blocked_))
    wait = std::min(wait, std::chrono::ceil<milliseconds>(
                              std::max(Clock::duration::zero(), *due - Clock::now())));
  return wait;
}

// Under the inbox's lock: the views set since, into the world's view index (what eviction
// protects); waiting loads no view holds any more are dropped.
void WorldPipeline::take_view_updates(Inbox::State& in) {
  if (in.view_updates.empty()) return;
  for (const auto& [owner, view] : in.view_updates) {
    state_->views.set(owner, view.first, view.second);
    if (config_.zones) config_.zones->viewing(owner, view.first, view.second);
  }
  in.view_updates.clear();
  loads_->drop_unviewed();
}

// Between batches and whenever the idle pipeline wakes: evict, checkpoint, the regions,
// and answer the batches whose appends landed (now: busy with loads it may not wait long).
void WorldPipeline::between_batches(Clock::time_point now) {
  keep_memory(now);
  checkpoints_turn(now);
  zone_regions_turn(now, false);
  repair_regions(now);
  finish_landed();
  if (config_.zones && config_.zones->records_waiting()) {
    drain_commits();  // a zone's records apply on the world its durable edits left
    zone_records_turn(*config_.zones, edit_world(), now, [&](AppliedRecords& r) {
      r.batch.fresh = remesh(*state_, r.batch.dirty, meshes_, commit_.get());
      for (const world::VoxelBox& box : r.touched) lod_->edited(box, now);
      answer(r.batch, true);
    });
  }
}

// A batch: every queued edit and inspection; then, on the world as the edits left it, one
// load pass within the work and memory budgets; then a level-of-detail pass.
void WorldPipeline::run() {
  const auto ready = [this](Inbox::State& in) {
    return in.stopping || in.append_landed || batch_ready(in);
  };
  for (;;) {
    while (!inbox_.wait_unless(ready, [this](const Inbox::State& in) { return idle_wait(in); })) {
      inbox_.locked([this](Inbox::State& in) { take_view_updates(in); });
      finish_landed();
      between_batches(Clock::now());
    }
    std::vector<OrderedTask> ordered;
    bool stopping = false, batch = false;
    inbox_.locked([&](Inbox::State& in) {
      stopping = in.stopping;
      batch = !stopping && batch_ready(in);
      if (!batch) return;  // stopping, or only an append landed: its batch is answered
      take_view_updates(in);
      ordered = in.scheduler.take_ordered();
      in.generated_ready = false;  // this batch installs what is ready
    });
    if (stopping) break;
    if (!batch) {
      finish_landed();
      continue;
    }
    const size_t ordered_count = ordered.size();
    const Clock::time_point now = Clock::now();
    // Column heights left by earlier batches (0: they are shared within a batch only).
    stats_.update([&](PipelineStats& s) { s.cached_columns = state_->column_heights.size(); });
    stats_.start_batch();
    // Earlier batches whose appends landed are answered before this batch applies (a failed
    // one is undone with every pending batch on top of it, newest first; this one must not
    // be on top of it yet, outside the pending ones).
    finish_landed();
    edit_pass(ordered, now);
    const size_t loaded = load_pass(now);
    lod_pass(Clock::now());
    state_->column_heights.clear();  // edits and loads both fill them
    stats_.update([](PipelineStats& s) { s.batches += 1; });
    between_batches(Clock::now());
    const double took = seconds_since(now);
    if (observer_.batch) observer_.batch(took, ordered_count, loaded);
    if (took > std::chrono::duration<double>(kSlowBatch).count()) stats_.log_slow(took, loaded);
  }
  drain_commits();  // what was applied is answered before anything is refused
  repair_regions(Clock::now(), true);
  drain_commits();
  drain_after_stop();
  // A rollback whose slices are not all in: no checkpoint covers its record, so the next
  // start replays it from the log.
  if (checkpoints_ && rollback_slices_.checkpoints_allowed())
    checkpoints_->last(*state_, commit_->last_seq(),
                       [this](const CheckpointResult& r) { record(r); });
  else if (checkpoints_)
    spdlog::warn(
        "no checkpoint at shutdown: a rollback was being put in place; the next start "
        "replays it from the log");
}

// Edits, region changes and inspections, in arrival order. Without a store the batch is
// answered here; with one, once its append has landed.
void WorldPipeline::edit_pass(std::vector<OrderedTask>& tasks, Clock::time_point now) {
  if (changes_regions(tasks)) zone_regions_turn(now, true);
  const bool durable = commit_ != nullptr;
  const EditRules rules{
      .limits = config_.limits,
      .max_generated_per_owner = config_.max_generated_per_owner,
      .durable = durable,
      .store_resting = durable && commit_->resting(now),
      .log_tail = checkpoints_ ? checkpoints_->log_tail(commit_->edits_in_flight()) : 0,
      .zones = config_.zones,
      .edit_ids = edit_ids_.get(),
      .frozen = rollback_slices_.frozen(),
      .last_seq = commit_ ? commit_->last_seq() : 0,
      .query_budget = &query_budget_};
  EditWorld world = edit_world();
  EditBatch b = apply_edits(tasks, world, regions_, rules, now);
  if (!b.any_edit) return;
  if (commit_ && (!b.accepted.empty() || b.regions.changed() || b.record))
    commit_->start(b, regions_.write_for_append(b.regions));  // overlaps the re-meshing
  const Clock::time_point start = Clock::now();
  b.fresh = remesh(*state_, b.dirty, meshes_, commit_.get());
  if (observer_.remesh && !b.dirty.empty()) observer_.remesh(seconds_since(start), b.dirty.size());
  if (!commit_) return answer(b, true);
  const Clock::time_point wait_until = b.appended_at + kAnswerWait;
  commit_->add(std::move(b));
  wait_for_answer(wait_until);
}

// Publishes a durable batch's meshes, or refuses its accepted edits (not durable: it was
// rolled back), then answers its edits and notifies the subscribers.
void WorldPipeline::answer(EditBatch& b, bool durable) {
  if (!durable) {
    refuse_undone(b, edit_ids_.get(), config_.zones);
  } else {
    if (checkpoints_) checkpoints_->logged(b.accepted.size());
    // The coarse levels re-mesh what durable edits changed.
    const Clock::time_point now = Clock::now();
    for (const EditTask* task : b.accepted) lod_->edited(world::touched_box(task->edit), now);
  }
  const std::vector<ChunkCoord> published =
      publish(*state_, meshes_, b.dirty, b.fresh, &b.edited_at);
  b.counts.meshes_published += published.size();
  count(b.counts);  // before the results: whoever waits on one sees its counts
  // Results, then subscribers: an edit's result is known once its meshes are published.
  if (durable) regions_.landed(b.regions);  // before the answers: a list after one sees it
  rollback_slices_.answer(b, durable, *lod_);
  answer_tasks(b, durable, published);
  subscribers_.notify(published);
}

// After its re-mesh, a batch waits a little for its append. Each pending batch is answered
// as soon as its append lands (oldest first), not when the newest's does.
void WorldPipeline::wait_for_answer(Clock::time_point until) {
  while (!commit_->empty()) {
    const Clock::time_point start = Clock::now();
    bool go_on = false;  // an edit arrived, or the pipeline stops
    inbox_.wait_until(until, [&](const Inbox::State& in) {
      go_on = in.stopping || in.scheduler.has_ordered();
      return go_on || commit_->oldest_landed();
    });
    commit_->waited_for_oldest(seconds_since(start));
    if (!commit_->oldest_landed()) break;  // the wait is over, or an edit arrived
    commit_->finish(SIZE_MAX);             // every batch whose append has landed
    if (go_on) break;
  }
  commit_->finish(kMaxPendingBatches);
}

void WorldPipeline::finish_landed() {
  inbox_.locked([](Inbox::State& in) { in.append_landed = false; });
  if (commit_) commit_->finish(SIZE_MAX);
}

void WorldPipeline::drain_commits() {
  if (commit_) commit_->finish(0);
}

// A cluster node reads the protected regions again when another node changed them or a
// batch changes some (`anyway`; not while the store rests), once the appends in flight land.
void WorldPipeline::zone_regions_turn(Clock::time_point now, bool anyway) {
  const bool due = config_.zones && (anyway || config_.zones->regions_changed());
  if (!due || commit_->resting(now)) return;
  drain_commits();
  take_zone_regions(*config_.zones, regions_, now);
}

// After a failed append that carried region changes: an append of the whole region table
// alone, once the store may be tried again (or, with `now_anyway`, at stop).
void WorldPipeline::repair_regions(Clock::time_point now, bool now_anyway) {
  if (!regions_.doubtful() || !commit_ || !commit_->empty()) return;
  if (!now_anyway && commit_->resting(now)) return;
  EditBatch b;  // no tasks: the append carries the region table (and forgets doubtful edits)
  commit_->start(b, regions_.write_for_append(b.regions));
  commit_->add(std::move(b));
}

// The batch's load pass, planned on the world as its edits left it: installs the terrain
// generated in the background, queues what the planned chunks still miss, meshes and
// publishes every waiting chunk whose neighbourhood is complete, then runs the finished
// requests' callbacks. Returns the chunks it planned to mesh.
size_t WorldPipeline::load_pass(Clock::time_point now) {
  LoadPlan plan;
  std::vector<LoadSlice> slices = inbox_.locked([&](Inbox::State& in) -> std::vector<LoadSlice> {
    // The views whose requests this pass takes must be the ones eviction protects: a view
    // set after the batch started would otherwise have its meshed chunks passed over here
    // (nothing to load) yet evicted below, and the session would wait for them forever.
    take_view_updates(in);
    if (!in.scheduler.has_loads()) return {};
    // Edits waiting to apply, or applied and waiting for the store to be answered: a short
    // pass, so that they are not held up behind it.
    const bool edits_waiting = in.scheduler.has_ordered() || (commit_ && !commit_->empty());
    return in.scheduler.take_loads(
        load_work_allowed(edits_waiting), [&](ChunkCoord c) { return loads_->cost(c, plan, now); },
        config_.load_scan_limit, now);
  });
  BatchCounts delta;
  loads_->wait_for(slices, plan);
  // After the new waiting chunks pinned their neighbourhoods: terrain ready for them is kept.
  delta.chunks_generated += loads_->install_generated(now);
  std::vector<ChunkCoord> published;
  if (loads_->waiting()) {
    std::vector<ChunkCoord> dirty = loads_->take_meshable(now, delta);
    finish_landed();  // not held up by the meshing
    // A mesh never shows an edit that is not durable: those batches are answered first.
    if (commit_ && commit_->near_pending_edits(dirty)) drain_commits();
    const Clock::time_point start = Clock::now();
    FreshMeshes fresh = remesh(*state_, dirty, meshes_, commit_.get());
    if (observer_.remesh && !dirty.empty()) observer_.remesh(seconds_since(start), dirty.size());
    published = publish(*state_, meshes_, dirty, fresh, nullptr);
    delta.meshes_published += published.size();
  }
  count(delta);
  stats_.update([&](PipelineStats& s) {
    s.chunks_generating = loads_->generating();
    s.meshes_waiting = loads_->waiting_count();
  });
  loads_->run_finished();
  subscribers_.notify(published);
  return plan.to_mesh.size();
}

// A level-of-detail pass: the layouts set since are taken (keys an owner now wants that
// were published before it did are routed to it), then the stage meshes within its time
// slice, putting off the meshes that read edits not durable yet; putting off too long, it
// waits for the appends. An edit arriving ends it: edits go first.
void WorldPipeline::lod_pass(Clock::time_point now) {
  std::unordered_map<LoadOwner, std::vector<LodKey>> updates;
  bool edits_waiting = false;
  inbox_.locked([&](Inbox::State& in) {
    updates.swap(in.lod_updates);
    edits_waiting = in.scheduler.has_ordered();
  });
  LodPublication late;
  for (auto& [owner, keys] : updates) {  // outside the lock
    std::vector<LodKey> published = lod_->set_wants(owner, std::move(keys));
    if (!published.empty())
      late.by_owner.emplace_back(owner,
                                 std::make_shared<const std::vector<LodKey>>(std::move(published)));
  }
  if (!late.by_owner.empty()) subscribers_.notify_lod(late);
  lod_blocked_ = false;
  if (!lod_->has_work(now)) return lod_->ran();
  if (commit_ && !commit_->empty() && lod_->held_back(now)) drain_commits();
  const Clock::time_point start = Clock::now();
  for (;;) {
    const std::vector<world::ChunkCoord> unsettled =
        commit_ ? commit_->pending_chunks() : std::vector<world::ChunkCoord>{};
    LodStage::RunResult r = lod_->run(Clock::now(), config_.lod_group_chunks, unsettled);
    if (r.deferred == 0) lod_->ran();
    if (!r.published.empty())
      subscribers_.notify_lod(LodPublication{r.published, lod_->route(r.published)});
    if (r.published.empty() && r.deferred > 0) {
      lod_blocked_ = true;  // until an append lands (batch_ready)
      return;
    }
    if (edits_waiting || Clock::now() - start >= config_.lod_pass_time ||
        !lod_->has_work(Clock::now()))
      return;
    const bool edit_or_stop = inbox_.locked(
        [](const Inbox::State& in) { return in.scheduler.has_ordered() || in.stopping; });
    if (edit_or_stop) return;
  }
}

// Evicts idle chunks now and then, and under memory pressure down to the budget's target
// (MemoryKeeper says when); decides whether loads must wait.
void WorldPipeline::keep_memory(Clock::time_point now) {
  WorldState& st = *state_;
  if (memory_.heap_due(now)) {
    if (const auto heap = read_heap_stats()) {
      const size_t parts = st.chunks.memory_bytes() + meshes_.memory_bytes() +
                           lod_->memory_bytes() + memory_.session_bytes() + on_its_way_bytes();
      memory_.heap_measured(now, heap->active, parts);
    }
  }
  if (const auto pass = memory_.due(now, resident_bytes(), memory_.other_bytes())) {
    drain_commits();  // chunks whose meshes wait for the store stay: answered first
    const size_t dropped =
        st.evict(meshes_, now, pass->idle, pass->min_age, pass->target_bytes, pass->max_scan);
    memory_.evicted(now, dropped, resident_bytes());
    stats_.update([&](PipelineStats& s) {
      s.chunks_evicted += dropped;
      StatsBook::residency(s, st);
    });
  }
  // Blocked: no room even once the terrain on its way has landed (while it is on its way,
  // load passes only wait for it: see batch_ready).
  if (memory_.update_blocked(resident_bytes()) && memory_.loads_blocked())
    stats_.update([](PipelineStats& s) { ++s.memory_blocked; });
}

void WorldPipeline::checkpoints_turn(Clock::time_point now) {
  if (!checkpoints_) return;
  checkpoints_->turn(
      *state_, now,
      [this] {
        drain_commits();
        return commit_->last_seq();
      },
      [this](const CheckpointResult& r) { record(r); }, rollback_slices_.checkpoints_allowed());
}

// A checkpoint taken in, at once (the observer may read the store before the next starts).
void WorldPipeline::record(const CheckpointResult& r) {
  if (observer_.checkpoint) observer_.checkpoint(r.seconds, r.coords.size(), r.bytes, r.ok);
  stats_.update([&](PipelineStats& s) {
    s.stored_chunks = state_->stored.size();
    s.unsaved_chunks = checkpoints_->unsaved_chunks();
    s.checkpoints += r.ok ? 1 : 0;
    s.checkpoint_failures += r.ok ? 0 : 1;
    if (r.ok) s.checkpoint_seq = r.seq;
  });
}

void WorldPipeline::count(const BatchCounts& delta) {
  stats_.count(delta, *state_, checkpoints_ ? checkpoints_->unsaved_chunks() : 0);
}

size_t WorldPipeline::resident_bytes() const {
  return state_->chunks.memory_bytes() + meshes_.memory_bytes() + lod_->memory_bytes() +
         memory_.other_bytes();
}

// Terrain generated for loads and not landed yet, and chunks a checkpoint holds copies of.
size_t WorldPipeline::on_its_way_bytes() const {
  return loads_->memory_bytes() + (checkpoints_ ? checkpoints_->memory_bytes() : 0);
}

// Load work within the memory budget, counting the terrain and meshes on their way at their
// worst case, so that passes taken while earlier ones wait for terrain do not overrun it.
size_t WorldPipeline::load_work_allowed(bool edits_waiting) const {
  const size_t full =
      edits_waiting ? config_.load_pass_work_while_edits_wait : config_.load_pass_work;
  return memory_.budget().load_work(resident_bytes() + on_its_way_bytes(), full);
}

void WorldPipeline::drain_after_stop() {
  std::vector<OrderedTask> ordered;
  std::vector<std::function<void()>> loads;
  inbox_.locked([&](Inbox::State& in) {
    ordered = in.scheduler.take_ordered();
    loads = in.scheduler.take_all_load_callbacks();
  });
  // An inspection runs (not cancelled): on the pipeline thread, state is still ours.
  for (OrderedTask& t : ordered) refuse_stopped(t, false);
  for (auto& done : loads) done();
  loads_->run_all_callbacks();
}

EditWorld WorldPipeline::edit_world() {
  EditWorld w{
      *state_, generator_, memory_, meshes_, checkpoints_.get(), memory_.other_bytes(), [this] {
        return resident_bytes();
      }};
  if (config_.zones) w.zone_chunks = config_.zones->zone_chunks();
  return w;
}

}  // namespace vox::pipeline
