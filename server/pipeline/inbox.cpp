#include "server/pipeline/inbox.hpp"

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/protected_regions.hpp"

namespace vox::pipeline {
namespace {

constexpr const char* kStoppedMessage = "shutting down: the world pipeline has stopped";

}  // namespace

void refuse_stopped(OrderedTask& task, bool cancelled) {
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
  } else if (auto* rollback = std::get_if<RollbackTask>(&task)) {
    if (rollback->done) rollback->done(false, 0);
  } else if (auto* query = std::get_if<QueryTask>(&task)) {
    QueryAnswer a;
    a.reason = world::RefusalReason::kShuttingDown;
    a.message = kStoppedMessage;
    if (query->done) query->done(a);
  } else {
    std::get<InspectTask>(task).run(cancelled);
  }
}

bool Inbox::add(OrderedTask& task) {
  {
    std::lock_guard lock(mutex_);
    if (state_.stopping) return false;
    state_.scheduler.add(std::move(task));
  }
  cv_.notify_one();
  return true;
}

bool Inbox::add_load(std::vector<world::ChunkCoord> chunks, std::function<void()>& done) {
  {
    std::lock_guard lock(mutex_);
    if (state_.stopping) return false;
    // One-off loads get owners from the top half (never budgeted); sessions use their ids.
    state_.scheduler.request(BatchScheduler::kUnlimitedOwners | state_.next_anonymous_owner++,
                             std::move(chunks), std::move(done));
  }
  cv_.notify_one();
  return true;
}

std::function<void()> Inbox::set_view(LoadOwner owner, world::ChunkCoord center, int radius,
                                      std::vector<world::ChunkCoord> chunks,
                                      uint64_t budget_group) {
  std::function<void()> replaced;
  {
    std::lock_guard lock(mutex_);
    if (state_.stopping) return {};
    replaced = state_.scheduler.request(owner, std::move(chunks), {}, budget_group);
    state_.view_updates[owner] = {center, radius};
  }
  cv_.notify_one();
  return replaced;
}

std::function<void()> Inbox::drop_view(LoadOwner owner) {
  std::function<void()> dropped;
  {
    std::lock_guard lock(mutex_);
    dropped = state_.scheduler.drop(owner);
    state_.view_updates[owner] = {{}, -1};
    state_.lod_updates[owner] = {};
  }
  cv_.notify_one();  // its level-of-detail meshes go now, not at the next idle wake
  return dropped;
}

void Inbox::set_lod_view(LoadOwner owner, std::vector<LodKey> keys) {
  {
    std::lock_guard lock(mutex_);
    if (state_.stopping) return;
    state_.lod_updates[owner] = std::move(keys);
  }
  cv_.notify_one();
}

void Inbox::append_landed() {
  {
    std::lock_guard lock(mutex_);
    state_.append_landed = true;
  }
  cv_.notify_one();
}

void Inbox::generated_ready() {
  {
    std::lock_guard lock(mutex_);
    state_.generated_ready = true;
  }
  cv_.notify_one();
}

void Inbox::poke() {
  { std::lock_guard lock(mutex_); }  // the pipeline is waiting, or will look
  cv_.notify_one();
}

void Inbox::stop() {
  {
    std::lock_guard lock(mutex_);
    state_.stopping = true;
  }
  cv_.notify_all();
}

Inbox::Counts Inbox::counts() const {
  std::lock_guard lock(mutex_);
  return {state_.scheduler.ordered_count(), state_.scheduler.queued_load_chunks(),
          state_.scheduler.load_owners()};
}

}  // namespace vox::pipeline
