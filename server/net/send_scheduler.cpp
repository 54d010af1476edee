#include "net/send_scheduler.hpp"

#include <algorithm>
#include <functional>

namespace vox::net {

using world::ChunkCoord;

int64_t SendScheduler::distance2(ChunkCoord c) const {
  const int64_t dx = c.x - center_.x, dy = c.y - center_.y, dz = c.z - center_.z;
  return dx * dx + dy * dy + dz * dz;
}

std::vector<ChunkCoord> SendScheduler::set_view(ChunkCoord center, int radius) {
  center_ = center;
  radius_ = radius;
  const int64_t r2 = static_cast<int64_t>(radius) * radius;
  std::vector<ChunkCoord> unloaded;
  for (auto it = visible_.begin(); it != visible_.end();) {
    if (distance2(it->first) > r2) {
      if (it->second.sent) unloaded.push_back(it->first);
      it = visible_.erase(it);
    } else {
      ++it;
    }
  }
  for (int dz = -radius; dz <= radius; ++dz)
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        if (dx * dx + dy * dy + dz * dz <= r2) visible_.try_emplace(center.offset(dx, dy, dz));
      }
  stale_.clear();  // re-ordered around the new centre
  deferred_.clear();
  for (auto& [c, held] : visible_) {
    held.queued = true;
    held.deferred = false;
    stale_.push_back({distance2(c), c});
  }
  std::make_heap(stale_.begin(), stale_.end(), std::greater<>());
  return unloaded;
}

void SendScheduler::mark_stale(ChunkCoord c) {
  // Most published chunks are outside this view: the distance says so without a lookup.
  if (distance2(c) > static_cast<int64_t>(radius_) * radius_) return;
  auto it = visible_.find(c);
  if (it == visible_.end() || it->second.queued) return;
  it->second.queued = true;
  stale_.push_back({distance2(c), c});
  std::push_heap(stale_.begin(), stale_.end(), std::greater<>());
}

void SendScheduler::release_deferred() {
  for (const ChunkCoord c : deferred_) {
    auto it = visible_.find(c);
    if (it == visible_.end()) continue;
    it->second.deferred = false;
    mark_stale(c);
  }
  deferred_.clear();
}

std::optional<SendScheduler::Send> SendScheduler::next(const Lookup& lookup, uint64_t first_unsendable) {
  while (!stale_.empty()) {
    std::pop_heap(stale_.begin(), stale_.end(), std::greater<>());
    const ChunkCoord c = stale_.back().second;
    stale_.pop_back();
    auto it = visible_.find(c);
    if (it == visible_.end()) continue;
    Held& held = it->second;
    held.queued = false;
    pipeline::MeshVersionPtr current = lookup(c);
    if (!current) continue;
    if (held.version && held.version->version >= current->version) continue;
    if (current->version >= first_unsendable) {
      if (!held.deferred) {
        held.deferred = true;
        deferred_.push_back(c);
      }
      continue;
    }
    if (!held.version && current->mesh.empty()) {
      held.version = std::move(current);  // nothing to draw; sent only once it changes
      continue;
    }
    // A client that never received the empty first version gets the new one in full.
    Send send{c, current, held.sent ? held.version : nullptr};
    held = {std::move(current), true};
    return send;
  }
  return std::nullopt;
}

void SendScheduler::clear() {
  visible_.clear();
  stale_.clear();
  deferred_.clear();
  radius_ = -1;
}

}  // namespace vox::net
