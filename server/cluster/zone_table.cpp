#include "server/cluster/zone_table.hpp"

#include <algorithm>

namespace vox::cluster {

void ZoneTable::taken(world::ZoneId zone, uint64_t epoch) {
  std::lock_guard lock(mutex_);
  Zone& z = zones_[zone];
  z.epoch = epoch;
  z.behind = true;
  z.leaving = false;
  z.swept = false;
}

void ZoneTable::leave(world::ZoneId zone, uint64_t epoch) {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it != zones_.end() && it->second.epoch == epoch) it->second.leaving = true;
}

bool ZoneTable::leaving(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  return it != zones_.end() && it->second.leaving;
}

void ZoneTable::lost(world::ZoneId zone, uint64_t epoch) {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || it->second.epoch != epoch) return;
  Zone& z = it->second;
  z.epoch.reset();
  z.behind = false;
  z.leaving = false;
  if (z.evicted) {
    z.evicted = false;
    z.fresh = true;
    z.applied = 0;
  }
}

bool ZoneTable::may_evict(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || !it->second.epoch || it->second.behind || it->second.leaving ||
      it->second.fresh)
    return false;
  it->second.evicted = true;
  return true;
}

ZoneTable::Position ZoneTable::position(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end()) return {};
  return {it->second.fresh ? 0 : it->second.applied, it->second.fresh};
}

std::optional<world::ZoneId> ZoneTable::next_fresh() const {
  std::lock_guard lock(mutex_);
  for (const auto& [zone, z] : zones_) {
    if (z.fresh) return zone;
  }
  return std::nullopt;
}

void ZoneTable::reset(world::ZoneId zone, uint64_t through) {
  std::lock_guard lock(mutex_);
  Zone& z = zones_[zone];
  z.fresh = false;
  z.applied = through;
}

std::optional<uint64_t> ZoneTable::writable(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || it->second.behind || it->second.leaving) return std::nullopt;
  return it->second.epoch;
}

std::optional<uint64_t> ZoneTable::appendable(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || it->second.behind) return std::nullopt;
  return it->second.epoch;
}

bool ZoneTable::held(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  return it != zones_.end() && it->second.epoch.has_value();
}

void ZoneTable::doubt(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || !it->second.epoch) return;
  it->second.behind = true;
  it->second.swept = false;
}

std::vector<ZoneTable::CheckpointZone> ZoneTable::start_checkpoint() {
  std::lock_guard lock(mutex_);
  std::vector<CheckpointZone> out;
  for (auto& [zone, z] : zones_) {
    if (!z.epoch || z.behind) continue;
    out.push_back({zone, *z.epoch, z.applied, !z.swept});
    z.swept = true;
  }
  return out;
}

void ZoneTable::committed(world::ZoneId zone, uint64_t last) {
  std::lock_guard lock(mutex_);
  Zone& z = zones_[zone];
  if (last > z.applied && !z.fresh) z.applied = last;  // fresh: read from the log again
}

std::optional<ZoneTable::CatchUp> ZoneTable::next_catch_up(
    std::optional<world::ZoneId> after) const {
  std::lock_guard lock(mutex_);
  const auto from = after ? zones_.upper_bound(*after) : zones_.begin();
  const auto behind = [](const auto& entry) {
    const Zone& z = entry.second;
    return z.epoch && z.behind && !z.fresh;
  };
  auto it = std::find_if(from, zones_.end(), behind);
  if (it == zones_.end()) {
    it = std::find_if(zones_.begin(), from, behind);
    if (it == from) return std::nullopt;
  }
  return CatchUp{it->first, *it->second.epoch, it->second.applied};
}

bool ZoneTable::catching_up() const { return next_catch_up().has_value(); }

void ZoneTable::caught_up(world::ZoneId zone, uint64_t epoch, uint64_t through, bool complete) {
  std::lock_guard lock(mutex_);
  Zone& z = zones_[zone];
  if (through > z.applied && !z.fresh) z.applied = through;
  if (complete && z.epoch == epoch && !z.fresh) z.behind = false;
}

uint64_t ZoneTable::applied(world::ZoneId zone) const { return position(zone).applied; }

std::vector<world::ZoneId> ZoneTable::writable_zones() const {
  std::lock_guard lock(mutex_);
  std::vector<world::ZoneId> out;
  for (const auto& [zone, z] : zones_) {
    if (z.epoch && !z.behind && !z.leaving) out.push_back(zone);
  }
  return out;
}

bool ZoneTable::has_edit(world::ZoneId zone, uint64_t id) const {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  return it != zones_.end() && it->second.edits.has(id);
}

void ZoneTable::note_edit(world::ZoneId zone, uint64_t id) {
  if (id == 0) return;
  std::lock_guard lock(mutex_);
  zones_[zone].edits.note(id);
}

std::vector<world::ZoneId> ZoneTable::known_unheld() const {
  std::lock_guard lock(mutex_);
  std::vector<world::ZoneId> out;
  for (const auto& [zone, z] : zones_) {
    if (!z.epoch && (z.edits.size() > 0 || (z.applied > 0 && !z.fresh))) out.push_back(zone);
  }
  return out;
}

void ZoneTable::forget(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  const auto it = zones_.find(zone);
  if (it == zones_.end() || it->second.epoch) return;
  Zone& z = it->second;
  z.edits = pipeline::EditIds(kRememberedEdits);
  if (z.applied > 0) {
    z.fresh = true;
    z.applied = 0;
  }
}

void ZoneTable::forget_edit(world::ZoneId zone, uint64_t id) {
  std::lock_guard lock(mutex_);
  if (const auto it = zones_.find(zone); it != zones_.end()) it->second.edits.forget(id);
}

}  // namespace vox::cluster
