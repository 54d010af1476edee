#include "server/pipeline/world_pipeline.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <unordered_set>

#include "server/pipeline/world_state.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/parallel.hpp"
#include "server/world/thread_name.hpp"

namespace vox::pipeline {

using world::ChunkCoord;
using world::ChunkCoordHash;

namespace {

constexpr const char* kStoppedMessage = "shutting down: the world pipeline has stopped";

// A task the stopped pipeline will not run: refused (an inspection runs, `cancelled`).
void refuse_shutting_down(OrderedTask& task, bool cancelled) {
  if (auto* e = std::get_if<EditTask>(&task)) {
    EditResult r;
    r.reason = world::RefusalReason::kShuttingDown;
    r.message = kStoppedMessage;
    if (e->done) e->done(r);
  } else if (auto* region = std::get_if<RegionTask>(&task)) {
    RegionOutcome r;
    r.status = RegionOutcome::Status::kShuttingDown;
    r.message = kStoppedMessage;
    if (region->done) region->done(r);
  } else {
    std::get<InspectTask>(task).run(cancelled);
  }
}

using CoordSet = std::unordered_set<ChunkCoord, ChunkCoordHash>;
// What an edit refused because the store could not write is told.
constexpr const char* kStorageMessage =
    "the world store cannot write now (disk full or database unreachable); the edit was not "
    "applied";
// ... and one refused because a checkpointed chunk it needs could not be read back.
constexpr const char* kStorageReadMessage =
    "a chunk this edit needs cannot be read from the world store now (unreachable, or the "
    "server's log names a damaged chunk); the edit was not applied";
constexpr const char* kLogFullMessage =
    "the world store is behind: its log holds as many edits as a checkpoint may leave "
    "unwritten; edits are taken again once the checkpoint in progress is written";

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
      // One connection for appends and reads: a read waits for the appends in flight.
      reader_(config_.store
                  ? std::make_unique<StoredChunkReader>(*config_.store, config_.store_retry,
                                                        [this] { commit_->wait_for_appends(); })
                  : nullptr),
      lod_(std::make_unique<LodStage>(generator_, *state_, config_.lod, reader_.get())),
      regions_(config_.limits) {
  if (config_.store) {
    state_->read_stored = [this](ChunkCoord c) { return reader_->read(c); };
    store::WorldStore& cp = config_.checkpoint_store ? *config_.checkpoint_store : *config_.store;
    checkpoints_ = std::make_unique<Checkpoints>(
        cp, config_.checkpoint_store != nullptr, config_.checkpoint, config_.keep_log,
        [this] { inbox_.poke(); }, Clock::now());
    commit_ = std::make_unique<DurableCommit>(
        *config_.store, config_.store_retry, [this] { inbox_.append_landed(); },
        DurableCommit::Hooks{.answer = [this](EditBatch& b, bool durable) { answer(b, durable); },
                             .undo =
                                 [this](EditBatch& b) {
                                   roll_back(b.undo);
                                   regions_.undo(b.regions);
                                 },
                             .committed =
                                 [this](const AppendOutcome& out, double waited) {
                                   if (observer_.commit && out.first)
                                     observer_.commit(out.seconds, out.edits, out.error.empty());
                                   if (observer_.commit_wait) observer_.commit_wait(waited);
                                 }});
    restore_from_store();  // before the pipeline's thread: may throw StoreError
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
}

WorldPipeline::~WorldPipeline() { stop(); }

void WorldPipeline::enqueue(OrderedTask task) {
  if (!inbox_.add(task)) refuse_shutting_down(task, true);  // answered on the caller's thread
}

void WorldPipeline::submit(world::Edit edit, EditCallback done, LoadOwner owner, std::string author,
                           bool bypass_regions) {
  enqueue(EditTask{std::move(edit), std::move(done), owner, Clock::now(), std::move(author),
                   bypass_regions});
}

void WorldPipeline::change_regions(RegionTask task) { enqueue(std::move(task)); }

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
  PipelineStats s;
  {
    std::lock_guard lock(stats_mutex_);
    s = stats_;
  }
  s.mesh_count = meshes_.size();
  s.mesh_bytes = meshes_.memory_bytes();
  lod_stats(s);
  s.other_bytes = other_bytes_.load(std::memory_order_relaxed);
  s.accounted_bytes = s.chunk_bytes + s.mesh_bytes + s.lod_mesh_bytes + s.other_bytes;
  s.loads_blocked = memory_.loads_blocked();
  const Inbox::Counts queued = inbox_.counts();
  s.queued_edits = queued.edits;
  s.queued_load_chunks = queued.load_chunks;
  s.load_owners = queued.load_owners;
  return s;
}

void WorldPipeline::stop() {
  inbox_.stop();
  if (thread_.joinable()) thread_.join();
  checkpoints_.reset();  // after the final checkpoint
  commit_.reset();       // idle: every batch was answered before thread_ ended
  loads_.reset();
}

// Under the inbox's lock. Loads whose pass the memory budget cuts to nothing while terrain
// is on its way wait for it (generated_ready), not in a busy loop.
bool WorldPipeline::batch_ready(Inbox::State& in) {
  const Clock::time_point now = Clock::now();
  // After a failed read of a stored chunk, a pass now and then tries it again.
  const bool retry_reads = loads_->waiting_for_store() && !reader_->backing_off(now);
  return in.scheduler.has_ordered() || in.generated_ready || retry_reads ||
         (in.scheduler.has_loads() && !memory_.loads_blocked() &&
          in.scheduler.has_ready_loads(now) && load_work_allowed(false) > 0) ||
         lod_ready(in, now);
}

// Under the inbox's lock: how long the idle pipeline may sleep, until the soonest of its
// parts is due (a wake-up ends it sooner).
std::chrono::milliseconds WorldPipeline::idle_wait(const Inbox::State& in) const {
  using std::chrono::milliseconds;
  milliseconds wait = memory_.next_look(in.scheduler.has_loads());
  // Unsaved chunks: their checkpoint (a finished one wakes us).
  if (checkpoints_ && checkpoints_->has_unsaved()) wait = std::min(wait, checkpoints_->interval());
  // A chunk the store could not give back, or a region table in doubt: try again then.
  if (loads_->waiting_for_store() || regions_.doubtful())
    wait = std::min(wait, std::chrono::duration_cast<milliseconds>(config_.store_retry));
  // A coarse chunk's re-mesh falls due (while a batch waits for the store, its landing
  // wakes us: the stage does not run before).
  if (const auto due = lod_->next_due(); due && !batches_in_flight())
    wait = std::min(wait, std::chrono::ceil<milliseconds>(
                              std::max(Clock::duration::zero(), *due - Clock::now())));
  return wait;
}

// What the parts do between batches, and whenever the idle pipeline wakes: answer the
// batches whose appends landed, evict, checkpoint, write a region table in doubt.
void WorldPipeline::between_batches(Clock::time_point now) {
  manage_memory(now);
  checkpoint_if_due(now);
  repair_regions(now);
  // Appends that landed meanwhile: answered now, not when the loop next waits (while loads
  // keep it busy it may not wait for a long time).
  finish_landed();
}

// A batch: every queued edit and inspection first; then, on the world as the edits left
// it, one load pass within what the work and memory budgets allow; then a level-of-detail
// pass. Between batches the parts take their turns.
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
    {
      std::lock_guard lock(stats_mutex_);
      stats_.cached_columns = state_->column_heights.size();  // what earlier batches left
    }
    batch_counts_ = {};  // the whole batch's, for the slow-batch log
    process_ordered(ordered, now);
    LoadPlan plan;
    std::vector<LoadSlice> loads = take_loads(plan, now);
    process_loads(loads, plan, now);
    lod_pass(Clock::now());
    // Column heights are shared within a batch only (edits and loads both fill them).
    state_->column_heights.clear();
    {
      std::lock_guard lock(stats_mutex_);
      stats_.batches += 1;
    }
    between_batches(Clock::now());
    const double took = seconds_since(now);
    if (observer_.batch) observer_.batch(took, ordered_count, plan.to_mesh.size());
    if (took > std::chrono::duration<double>(kSlowBatch).count()) {
      spdlog::warn(
          "pipeline: a batch took {:.0f} ms ({} edits, {} chunks loaded, {} generated, {} meshes "
          "published)",
          took * 1000, batch_counts_.edits_applied + batch_counts_.edits_refused,
          plan.to_mesh.size(), batch_counts_.chunks_generated, batch_counts_.meshes_published);
    }
  }
  finish_pending(0);  // what was applied is answered before anything is refused
  repair_regions(Clock::now(), true);
  finish_pending(0);
  drain_after_stop();
  final_checkpoint();
}

// Answers the batches whose appends have landed (outside the inbox's lock).
void WorldPipeline::finish_landed() {
  inbox_.locked([](Inbox::State& in) { in.append_landed = false; });
  finish_pending(SIZE_MAX);
}

void WorldPipeline::drain_after_stop() {
  std::vector<OrderedTask> ordered;
  std::vector<std::function<void()>> loads;
  inbox_.locked([&](Inbox::State& in) {
    ordered = in.scheduler.take_ordered();
    loads = in.scheduler.take_all_load_callbacks();
  });
  // An inspection runs (not cancelled): on the pipeline thread, state is still ours.
  for (OrderedTask& t : ordered) refuse_shutting_down(t, false);
  for (auto& done : loads) done();
  loads_->run_all_callbacks();
}

// Edits, region changes and inspections, in arrival order. Without a store the batch is answered
// here; with one, once its append has landed (finish_pending).
void WorldPipeline::process_ordered(std::vector<OrderedTask>& tasks, Clock::time_point now) {
  // Earlier batches whose appends landed: answered now, and before this batch applies (a
  // failed one is undone with every pending batch on top of it, newest first; this one
  // must not be on top of it yet, outside the pending ones).
  finish_landed();
  EditBatch b = apply_batch(tasks, now);
  if (!b.any_edit) return;
  if (commit_ && (!b.accepted.empty() || b.regions.changed()))
    commit_->start(b, regions_.write_for_append(b.regions));  // overlaps the re-meshing
  b.fresh = remesh(b.dirty);
  if (!commit_) return answer(b, true);
  const Clock::time_point wait_until = b.appended_at + kAnswerWait;
  commit_->add(std::move(b));
  wait_for_answer(wait_until);
}

// Applies the batch's edits (validated, within the generation limits; refused untried
// while the store rests after a failure) and runs its inspections.
EditBatch WorldPipeline::apply_batch(std::vector<OrderedTask>& tasks, Clock::time_point now) {
  EditBatch b;
  memory_.new_batch();
  b.edit_dirty.resize(tasks.size());
  b.results.resize(tasks.size());
  std::unordered_map<LoadOwner, size_t> generated_by;  // this batch's terrain per sender
  const bool durable = config_.store != nullptr;
  const bool store_resting = durable && commit_->resting(now);
  const uint64_t log_tail = durable ? logged_since_checkpoint() : 0;
  BatchCounts& delta = b.counts;
  EditWorld world_access = edit_world();
  for (size_t t = 0; t < tasks.size(); ++t) {
    if (auto* insp = std::get_if<InspectTask>(&tasks[t])) {
      // Sees every edit queued before it applied; the meshes of this batch are not
      // published yet, but densities are final.
      insp->run(false);
      continue;
    }
    if (auto* region = std::get_if<RegionTask>(&tasks[t])) {
      b.any_edit = true;  // answered with the batch
      regions_.apply(*region, t, store_resting, b.regions, kStorageMessage);
      continue;
    }
    const EditTask& task = std::get<EditTask>(tasks[t]);
    const world::Edit& edit = task.edit;
    EditResult& result = b.results[t];
    b.any_edit = true;
    if (auto refusal = world::validate(edit, config_.limits)) {
      result.reason = refusal->reason;
      result.message = refusal->message;
      ++delta.edits_refused;
      continue;
    }
    if (store_resting) {
      result.reason = world::RefusalReason::kStorageUnavailable;
      result.message = kStorageMessage;
      ++delta.edits_refused;
      continue;
    }
    if (durable && checkpoints_->log_full(log_tail + b.accepted.size())) {
      result.reason = world::RefusalReason::kServerBusy;
      result.message = kLogFullMessage;
      ++delta.edits_refused;
      ++delta.edits_refused_busy;
      continue;
    }
    world::Protection protection;
    if (!task.bypass_regions && !regions_.in_force().empty())
      protection = world::protection_for(regions_.in_force(), edit, task.author);
    if (protection.forbidden_by) {
      result.reason = world::RefusalReason::kForbidden;
      result.message =
          "it lies wholly inside protected region " + std::to_string(*protection.forbidden_by);
      ++delta.edits_refused;
      continue;
    }
    size_t& generated = generated_by[task.owner];
    const size_t max_generate = task.owner == 0
                                    ? SIZE_MAX
                                    : config_.max_generated_per_owner -
                                          std::min(generated, config_.max_generated_per_owner);
    const world::RefusalReason refused =
        apply_edit_step(world_access, edit, now, max_generate, b.edit_dirty[t], result,
                        durable ? &b.undo : nullptr, protection.keep);
    if (refused != world::RefusalReason::kNone) {
      result.reason = refused;
      result.message =
          refused == world::RefusalReason::kServerBusy
              ? "the server's memory budget is full: edits needing new terrain are refused"
          : refused == world::RefusalReason::kStorageUnavailable
              ? kStorageReadMessage
              : "your edits made the server generate too much terrain at once";
      ++delta.edits_refused;
      delta.edits_refused_busy += refused == world::RefusalReason::kServerBusy ? 1 : 0;
      continue;
    }
    generated += result.chunks_generated;
    result.accepted = true;
    result.clipped_by = std::move(protection.regions);
    b.accepted.push_back(&task);
    b.keep.push_back(std::move(protection.keep));
    ++delta.edits_applied;
    delta.chunks_generated += result.chunks_generated;
    b.dirty.insert(b.dirty.end(), b.edit_dirty[t].begin(), b.edit_dirty[t].end());
    for (const ChunkCoord& c : b.edit_dirty[t])
      b.edited_at.try_emplace(c, task.submitted);  // arrival order
  }
  b.tasks = std::move(tasks);
  regions_.seal(b.regions);
  return b;
}

void WorldPipeline::answer(EditBatch& b, bool durable) {
  if (!durable) {
    for (EditResult& r : b.results) {
      if (!r.accepted) continue;
      r.accepted = false;
      r.reason = world::RefusalReason::kStorageUnavailable;
      r.message = kStorageMessage;
    }
    for (auto& d : b.edit_dirty) d.clear();
    b.counts.edits_applied -= b.accepted.size();
    b.counts.edits_refused += b.accepted.size();
    b.dirty.clear();
    b.fresh.clear();
  } else {
    if (checkpoints_) checkpoints_->logged(b.accepted.size());
    lod_edited(b, Clock::now());
  }
  const std::vector<ChunkCoord> published = publish(b.dirty, b.fresh, &b.edited_at);
  const CoordSet published_set(published.begin(), published.end());
  b.counts.meshes_published += published.size();
  count(b.counts);  // before the results: whoever waits on one sees its counts
  // Results, then subscribers: an edit's result is known once its meshes are published.
  if (durable) regions_.landed(b.regions);  // before the answers: a list after one sees it
  for (auto& [t, outcome] : b.regions.outcomes) {
    if (!durable && outcome.status == RegionOutcome::Status::kOk) {
      outcome.status = RegionOutcome::Status::kStorageUnavailable;
      outcome.message = kStorageMessage;
    }
    if (auto& done = std::get<RegionTask>(b.tasks[t]).done) done(outcome);
  }
  for (size_t t = 0; t < b.tasks.size(); ++t) {
    auto* task = std::get_if<EditTask>(&b.tasks[t]);
    if (!task) continue;
    auto& r = b.results[t];
    for (const ChunkCoord& c : b.edit_dirty[t]) {
      if (published_set.count(c)) r.changed_chunks.push_back(c);
    }
    std::sort(r.changed_chunks.begin(), r.changed_chunks.end());
    r.changed_chunks.erase(std::unique(r.changed_chunks.begin(), r.changed_chunks.end()),
                           r.changed_chunks.end());
    if (task->done) task->done(r);
  }
  subscribers_.notify(published);
}

EditWorld WorldPipeline::edit_world() {
  return {*state_,
          generator_,
          memory_,
          meshes_,
          checkpoints_.get(),
          other_bytes_.load(std::memory_order_relaxed),
          [this] { return resident_bytes(); }};
}

void WorldPipeline::count(const BatchCounts& delta) {
  const WorldState& st = *state_;
  batch_counts_.edits_applied += delta.edits_applied;
  batch_counts_.edits_refused += delta.edits_refused;
  batch_counts_.meshes_published += delta.meshes_published;
  batch_counts_.chunks_generated += delta.chunks_generated;
  std::lock_guard lock(stats_mutex_);
  stats_.edits_applied += delta.edits_applied;
  stats_.edits_refused += delta.edits_refused;
  stats_.edits_refused_busy += delta.edits_refused_busy;
  stats_.meshes_published += delta.meshes_published;
  stats_.chunks_generated += delta.chunks_generated;
  stats_.loaded_chunks = st.chunks.size();
  stats_.modified_chunks = st.modified_count;
  stats_.chunk_bytes = st.chunks.memory_bytes();
  stats_.unsaved_chunks = checkpoints_ ? checkpoints_->unsaved_chunks() : 0;
  stats_.stored_chunks = st.stored.size();
}

}  // namespace vox::pipeline
