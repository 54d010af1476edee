#include "server/cluster/part_completer.hpp"

#include <spdlog/spdlog.h>

#include "server/cluster/zone_wire.hpp"
#include "server/world/thread_name.hpp"

namespace vox::cluster {

PartCompleter::PartCompleter(Config config, Writable writable, Submit submit)
    : config_(std::move(config)),
      writable_(std::move(writable)),
      submit_(std::move(submit)),
      db_(config_.uri, config_.node, config_.lease),
      thread_(named_thread("vox-parts", [this] { run(); })) {}

PartCompleter::~PartCompleter() { stop(); }

void PartCompleter::stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void PartCompleter::run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    wake_.wait_for(lock, config_.every, [this] { return stop_; });
    if (stop_) break;
    lock.unlock();
    try {
      sweep();
    } catch (const store::StoreError& e) {  // tried again next time
      spdlog::warn("cluster: cannot read the parts left to complete: {}", e.what());
    }
    lock.lock();
  }
}

void PartCompleter::sweep() {
  const std::vector<world::ZoneId> zones = writable_();
  if (zones.empty()) return;
  size_t room = 0;
  {
    std::lock_guard lock(mutex_);
    room = config_.max_in_flight - std::min(config_.max_in_flight, in_flight_.size());
  }
  if (room == 0) return;
  std::set<std::pair<world::ZoneId, uint64_t>> drop;
  {
    std::lock_guard lock(mutex_);
    drop.swap(to_drop_);
  }
  for (const auto& [zone, id] : drop) db_.drop_pending(zone, id);
  for (const store::ZonePending& p : db_.read_pending(zones, config_.age, room)) {
    std::string why;
    const std::optional<store::LoggedEdit> part =
        decode_zone_edit(store::ZoneRecord{0, p.unix_ms, p.payload, p.edit_id}, &why);
    const std::string where =
        "zone (" + std::to_string(p.zone.x) + ", " + std::to_string(p.zone.z) + ")";
    if (!part) {  // written by a node of this world: a bug, or a damaged row
      spdlog::error("cluster: the part of edit {} left for {} cannot be read ({}); removed",
                    p.edit_id, where, why);
      db_.drop_pending(p.zone, p.edit_id);  // else it would hold a place for ever
      continue;
    }
    {
      std::lock_guard lock(mutex_);
      if (!in_flight_.emplace(p.zone, p.edit_id).second) continue;  // still on its way
    }
    spdlog::info(
        "cluster: completing edit {} in {} (another zone's part of it was logged; "
        "this one never came)",
        p.edit_id, where);
    pipeline::EditTask task;
    task.edit = part->edit;
    task.author = part->author;
    task.forwarded = true;
    task.edit_id = p.edit_id;
    task.part = p.zone;
    task.recorded_keep = part->keep;  // as the holder that logged the edit clipped it
    task.done = [this, zone = p.zone, id = p.edit_id, where](const pipeline::EditResult& r) {
      {
        std::lock_guard lock(mutex_);
        in_flight_.erase({zone, id});
      }
      using world::RefusalReason;
      if (r.accepted) {
        completed_.fetch_add(1, std::memory_order_relaxed);
      } else if (r.reason == RefusalReason::kStorageUnavailable ||
                 r.reason == RefusalReason::kServerBusy ||
                 r.reason == RefusalReason::kShuttingDown) {
        spdlog::warn("cluster: edit {} in {} not completed yet: {}", id, where, r.message);
      } else {  // never applicable (a damaged row that still decodes): not tried again
        spdlog::error("cluster: the part of edit {} left for {} cannot be applied ({}); removed",
                      id, where, r.message);
        std::lock_guard lock(mutex_);
        if (to_drop_.size() < config_.max_in_flight) to_drop_.emplace(zone, id);
      }
    };
    submit_(std::move(task));
  }
}

}  // namespace vox::cluster
