#include "server/pipeline/protected_regions.hpp"

#include <algorithm>

namespace vox::pipeline {

ProtectedRegions::ProtectedRegions(world::EditLimits limits) : limits_(limits) {}

void ProtectedRegions::restore(store::RegionTable table) {
  regions_ = std::move(table.regions);
  next_id_ = std::max(next_id_, table.next_id);  // ids are never given twice
  doubtful_ = false;
  std::lock_guard lock(published_mutex_);
  published_ = std::make_shared<const Regions>(regions_);
}

std::shared_ptr<const ProtectedRegions::Regions> ProtectedRegions::published() const {
  std::lock_guard lock(published_mutex_);
  return published_;
}

void ProtectedRegions::apply(const RegionTask& task, size_t index, bool store_resting,
                             RegionChanges& changes, const std::string& storage_message) {
  using Status = RegionOutcome::Status;
  RegionOutcome out;
  auto refuse = [&](Status status, std::string message) {
    out.status = status;
    out.message = std::move(message);
    changes.outcomes.emplace_back(index, std::move(out));
  };
  if (store_resting) return refuse(Status::kStorageUnavailable, storage_message);
  Regions next = regions_;
  if (task.add) {
    const world::RegionLimits limits;
    if (regions_.size() >= limits.max_regions)
      return refuse(Status::kTooMany, "the world has " + std::to_string(limits.max_regions) +
                                          " protected regions, the most it may have");
    if (auto why = world::validate_region(*task.add, limits_, limits))
      return refuse(Status::kBadValue, *why);
    out.region = *task.add;
    out.region.id = next_id_++;
    next.push_back(out.region);
    if (!changes.write) changes.write.emplace();
    changes.write->upsert.push_back(out.region);
  } else {
    auto it = std::find_if(next.begin(), next.end(),
                           [&task](const world::Region& r) { return r.id == task.remove_id; });
    if (it == next.end())
      return refuse(Status::kNotFound, "no protected region " + std::to_string(task.remove_id));
    out.region = *it;
    next.erase(it);
    if (!changes.write) changes.write.emplace();
    changes.write->remove.push_back(out.region.id);
  }
  if (!changes.before) changes.before = regions_;
  regions_ = std::move(next);
  changes.outcomes.emplace_back(index, std::move(out));
}

void ProtectedRegions::seal(RegionChanges& changes) const {
  if (changes.before) changes.after = std::make_shared<const Regions>(regions_);
}

std::optional<store::RegionWrite> ProtectedRegions::write_for_append(RegionChanges& changes) {
  std::optional<store::RegionWrite> write = std::move(changes.write);
  changes.write.reset();
  if (doubtful_) {
    write.emplace();
    write->whole = true;
    write->upsert = regions_;
  }
  if (write) {
    write->next_id = next_id_;
    changes.carried = true;
  }
  return write;
}

void ProtectedRegions::landed(const RegionChanges& changes) {
  if (changes.carried) doubtful_ = false;
  if (!changes.after) return;
  std::lock_guard lock(published_mutex_);
  published_ = changes.after;
}

void ProtectedRegions::undo(RegionChanges& changes) {
  if (changes.before) regions_ = std::move(*changes.before);
  changes.before.reset();
  doubtful_ = doubtful_ || changes.carried;
}

}  // namespace vox::pipeline
