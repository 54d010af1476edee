// The world's protected regions as the pipeline keeps them: the table in force (with the
// changes of batches still waiting for the store), the table readers see (as of the last
// durable change), the next id, and whether the store's copy is in doubt after a failed
// append that carried changes (then the next append writes the whole table). Region tasks
// change it in order with the edits around them (apply); a batch's changes are published
// when its append is durable and undone when it fails. Pipeline thread only, but
// published() (any thread).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/store/world_store.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"

namespace vox::pipeline {

// The answer to a RegionTask, once durable (or refused).
struct RegionOutcome {
  enum class Status : uint8_t {
    kOk,
    kBadValue,
    kNotFound,
    kTooMany,
    kStorageUnavailable,
    kShuttingDown
  };
  Status status = Status::kOk;
  std::string message;   // why it was refused
  world::Region region;  // the region added or removed
};

// What one batch's region tasks did: their outcomes (by task index), the table before its
// first change (restored when the batch is undone) and after its last (published when
// durable), and the changes for the store.
struct RegionChanges {
  std::vector<std::pair<size_t, RegionOutcome>> outcomes;
  std::optional<std::vector<world::Region>> before;
  std::shared_ptr<const std::vector<world::Region>> after;
  std::optional<store::RegionWrite> write;
  bool carried = false;  // the batch's append writes regions

  bool changed() const { return before.has_value(); }
};

class ProtectedRegions {
 public:
  using Regions = std::vector<world::Region>;

  explicit ProtectedRegions(world::EditLimits limits);

  // The store's table: at start (before the pipeline thread runs), and on a cluster node
  // whenever another node changed the cluster's (with no append in flight). Not in doubt.
  void restore(store::RegionTable table);

  // The regions in force, pending changes included: edits are clipped by these.
  const Regions& in_force() const { return regions_; }
  // Any thread: the regions as of the last durable change.
  std::shared_ptr<const Regions> published() const;

  // Task `index` of a batch: adds or removes a region in force and records it in
  // `changes`, or refuses it (an outcome with the reason). `store_resting`: the store
  // failed lately and is not tried yet.
  void apply(const RegionTask& task, size_t index, bool store_resting, RegionChanges& changes,
             const std::string& storage_message);
  // After the batch's last task: the table its changes lead to.
  void seal(RegionChanges& changes) const;

  // What the batch's append writes of the regions: its changes; after a failed append
  // that carried some (it may have landed or not), the whole table. Sets changes.carried.
  std::optional<store::RegionWrite> write_for_append(RegionChanges& changes);
  // Whether the store's table is in doubt: an append of it alone is due.
  bool doubtful() const { return doubtful_; }
  // The batch's append is durable: its table is the readers'.
  void landed(const RegionChanges& changes);
  // The batch's append failed (it and every later one undone, newest first).
  void undo(RegionChanges& changes);

 private:
  const world::EditLimits limits_;
  Regions regions_;
  uint64_t next_id_ = 1;
  bool doubtful_ = false;
  mutable std::mutex published_mutex_;  // leaf lock, guards published_
  std::shared_ptr<const Regions> published_ = std::make_shared<const Regions>();
};

}  // namespace vox::pipeline
