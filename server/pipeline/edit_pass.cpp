#include "server/pipeline/edit_pass.hpp"

#include <algorithm>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/query_pass.hpp"
#include "server/pipeline/zone_authority.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

// ... and one refused because a checkpointed chunk it needs could not be read back.
constexpr const char* kStorageReadMessage =
    "a chunk this edit needs cannot be read from the world store now (unreachable, or the "
    "server's log names a damaged chunk); the edit was not applied";
constexpr const char* kLogFullMessage =
    "the world store is behind: its log holds as many edits as a checkpoint may leave "
    "unwritten; edits are taken again once the checkpoint in progress is written";

// The samples an edit reads: a smooth reads around what it writes.
world::VoxelBox read_box(const world::Edit& edit) {
  const auto* smooth = std::get_if<world::Smooth>(&edit);
  return smooth ? world::smooth_read_box(*smooth) : world::touched_box(edit);
}

void refuse(EditResult& result, world::RefusalReason reason, std::string message,
            BatchCounts& counts) {
  result.reason = reason;
  result.message = std::move(message);
  ++counts.edits_refused;
  counts.edits_refused_busy += reason == world::RefusalReason::kServerBusy ? 1 : 0;
}

}  // namespace

bool changes_regions(const std::vector<OrderedTask>& tasks) {
  return std::any_of(tasks.begin(), tasks.end(),
                     [](const OrderedTask& t) { return std::holds_alternative<RegionTask>(t); });
}

namespace {

bool reaches(const std::unordered_set<ChunkCoord, world::ChunkCoordHash>& frozen,
             const world::Edit& edit) {
  for (const ChunkCoord& c : world::chunks_overlapping(read_box(edit)))
    if (frozen.count(c)) return true;
  return false;
}

// A rollback's step in its place among the batch's tasks (RollbackTask). An install is
// answered with the batch: results[t].accepted when it was put in place.
void rollback_step(RollbackTask& task, EditBatch& b, size_t t, EditWorld& world,
                   const EditRules& rules, Clock::time_point now) {
  using Kind = RollbackTask::Kind;
  if (task.kind == Kind::kFreeze) {
    // After a failed append, appends in doubt may still be in the log: nothing is read.
    if (rules.store_resting) {
      if (task.done) task.done(false, 0);
      return;
    }
    if (rules.frozen) rules.frozen->insert(task.coords.begin(), task.coords.end());
    // The edits accepted so far are logged with this batch, before anything frozen now.
    if (task.done) task.done(true, rules.last_seq + b.accepted.size());
    return;
  }
  if (task.kind == Kind::kThaw) {
    if (rules.frozen)
      for (const ChunkCoord& c : task.coords) rules.frozen->erase(c);
    if (task.done) task.done(true, 0);
    return;
  }
  b.any_edit = true;  // answered with the batch
  if (rules.store_resting) return;
  std::vector<ChunkCoord> dirtied;
  if (install_chunks(world, task.chunks, now, dirtied, rules.durable ? &b.undo : nullptr) !=
      world::RefusalReason::kNone)
    return;
  b.results[t].accepted = true;
  if (task.undoes) b.record = EditBatch::Record{b.accepted.size(), *task.undoes, task.by};
  b.dirty.insert(b.dirty.end(), dirtied.begin(), dirtied.end());
  b.edit_dirty[t] = std::move(dirtied);
}

}  // namespace

EditBatch apply_edits(std::vector<OrderedTask>& tasks, EditWorld& world, ProtectedRegions& regions,
                      const EditRules& rules, Clock::time_point now) {
  EditBatch b;
  world.memory.new_batch();
  b.edit_dirty.resize(tasks.size());
  b.results.resize(tasks.size());
  std::unordered_map<LoadOwner, size_t> generated_by;  // this batch's terrain per sender
  BatchCounts& delta = b.counts;
  for (size_t t = 0; t < tasks.size(); ++t) {
    if (auto* insp = std::get_if<InspectTask>(&tasks[t])) {
      // Sees every edit queued before it applied; the meshes of this batch are not
      // published yet, but densities are final.
      insp->run(false);
      continue;
    }
    if (auto* region = std::get_if<RegionTask>(&tasks[t])) {
      b.any_edit = true;  // answered with the batch
      regions.apply(*region, t, rules.store_resting, b.regions, kStorageMessage);
      continue;
    }
    if (auto* query = std::get_if<QueryTask>(&tasks[t])) {
      answer_query(*query, world, rules.query_budget, now);
      continue;
    }
    if (auto* rollback = std::get_if<RollbackTask>(&tasks[t])) {
      rollback_step(*rollback, b, t, world, rules, now);
      continue;
    }
    EditTask& task = std::get<EditTask>(tasks[t]);
    const world::Edit& edit = task.edit;
    EditResult& result = b.results[t];
    b.any_edit = true;
    if (auto refusal = world::validate(edit, rules.limits)) {
      refuse(result, refusal->reason, refusal->message, delta);
      continue;
    }
    if (rules.frozen && !rules.frozen->empty() && reaches(*rules.frozen, edit)) {
      refuse(result, world::RefusalReason::kServerBusy, kRollingBackMessage, delta);
      continue;
    }
    if (rules.store_resting) {
      refuse(result, world::RefusalReason::kStorageUnavailable, kStorageMessage, delta);
      continue;
    }
    if (rules.edit_ids && rules.edit_ids->has(task.edit_id)) {
      result.accepted = result.already_applied = true;  // a resend: its answer was lost
      continue;
    }
    std::vector<world::VoxelBox> zone_keep;  // a part's: the samples of its other zones
    if (rules.zones) {
      std::string why;
      const ZoneAuthority::Verdict verdict =
          rules.zones->admit(task, read_box(edit), zone_keep, why);
      if (verdict == ZoneAuthority::Verdict::kForwarded) continue;  // the holder answers it
      if (verdict == ZoneAuthority::Verdict::kRefused ||
          verdict == ZoneAuthority::Verdict::kNotHere) {
        result.zone_moving = verdict == ZoneAuthority::Verdict::kNotHere;
        refuse(result, world::RefusalReason::kStorageUnavailable, std::move(why), delta);
        continue;
      }
      if (verdict == ZoneAuthority::Verdict::kAlreadyApplied) {
        result.accepted = result.already_applied = true;
        result.message = std::move(why);
        continue;
      }
    }
    if (world.checkpoints && world.checkpoints->log_full(rules.log_tail + b.accepted.size())) {
      refuse(result, world::RefusalReason::kServerBusy, kLogFullMessage, delta);
      continue;
    }
    world::Protection protection;
    if (task.recorded_keep)
      protection.keep = *task.recorded_keep;  // clipped by the holder that logged its edit
    else if (!task.bypass_regions && !regions.in_force().empty())
      protection = world::protection_for(regions.in_force(), edit, task.author);
    protection.keep.insert(protection.keep.end(), zone_keep.begin(), zone_keep.end());
    if (protection.forbidden_by) {
      refuse(result, world::RefusalReason::kForbidden,
             "it lies wholly inside protected region " + std::to_string(*protection.forbidden_by),
             delta);
      continue;
    }
    size_t& generated = generated_by[task.owner];
    const size_t max_generate =
        task.owner == 0
            ? SIZE_MAX
            : rules.max_generated_per_owner - std::min(generated, rules.max_generated_per_owner);
    const world::RefusalReason refused =
        apply_edit_step(world, edit, now, max_generate, b.edit_dirty[t], result,
                        rules.durable ? &b.undo : nullptr, protection.keep);
    if (refused != world::RefusalReason::kNone) {
      refuse(result, refused,
             refused == world::RefusalReason::kServerBusy
                 ? "the server's memory budget is full: edits needing new terrain are refused"
             : refused == world::RefusalReason::kStorageUnavailable
                 ? kStorageReadMessage
                 : "your edits made the server generate too much terrain at once",
             delta);
      continue;
    }
    generated += result.chunks_generated;
    result.accepted = true;
    result.clipped_by = std::move(protection.regions);
    if (rules.zones) rules.zones->accepted(task);
    if (rules.edit_ids) rules.edit_ids->note(task.edit_id);
    b.accepted.push_back(&task);
    b.keep.push_back(std::move(protection.keep));
    ++delta.edits_applied;
    delta.chunks_generated += result.chunks_generated;
    b.dirty.insert(b.dirty.end(), b.edit_dirty[t].begin(), b.edit_dirty[t].end());
    for (const ChunkCoord& c : b.edit_dirty[t])
      b.edited_at.try_emplace(c, task.submitted);  // arrival order
  }
  b.tasks = std::move(tasks);
  regions.seal(b.regions);
  return b;
}

void refuse_undone(EditBatch& b, EditIds* ids, ZoneAuthority* zones) {
  for (const EditTask* t : b.accepted) {
    if (ids) ids->forget(t->edit_id);
    if (zones) zones->undone(*t);
  }
  for (EditResult& r : b.results) {
    if (!r.accepted) continue;
    r.already_applied = false;
    r.accepted = false;
    r.reason = world::RefusalReason::kStorageUnavailable;
    r.message = kStorageMessage;
    r.zone_moving = b.zone_moved;  // a forwarded edit is asked again at the zone's holder
  }
  for (auto& d : b.edit_dirty) d.clear();
  b.counts.edits_applied -= b.accepted.size();
  b.counts.edits_refused += b.accepted.size();
  b.dirty.clear();
  b.fresh.clear();
}

void answer_tasks(EditBatch& b, bool durable, const std::vector<ChunkCoord>& published) {
  for (auto& [t, outcome] : b.regions.outcomes) {
    if (!durable && outcome.status == RegionOutcome::Status::kOk) {
      outcome.status = RegionOutcome::Status::kStorageUnavailable;
      outcome.message = kStorageMessage;
    }
    if (auto& done = std::get<RegionTask>(b.tasks[t]).done) done(outcome);
  }
  const std::unordered_set<ChunkCoord, world::ChunkCoordHash> published_set(published.begin(),
                                                                            published.end());
  for (size_t t = 0; t < b.tasks.size(); ++t) {
    auto* task = std::get_if<EditTask>(&b.tasks[t]);
    if (!task) continue;
    auto& r = b.results[t];
    for (const ChunkCoord& c : b.edit_dirty[t])
      if (published_set.count(c)) r.changed_chunks.push_back(c);
    std::sort(r.changed_chunks.begin(), r.changed_chunks.end());
    r.changed_chunks.erase(std::unique(r.changed_chunks.begin(), r.changed_chunks.end()),
                           r.changed_chunks.end());
    if (task->done) task->done(r);
  }
}

}  // namespace vox::pipeline
