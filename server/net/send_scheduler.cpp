#include "server/net/send_scheduler.hpp"

#include <algorithm>
#include <functional>

namespace vox::net {

using world::ChunkCoord;

int64_t SendScheduler::distance2(ChunkCoord c) const {
  const int64_t dx = c.x - center_.x, dy = c.y - center_.y, dz = c.z - center_.z;
  return dx * dx + dy * dy + dz * dz;
}

std::vector<ChunkCoord> SendScheduler::set_view(ChunkCoord center, int radius, const Keep& keep) {
  center_ = center;
  radius_ = radius;
  const int64_t r2 = static_cast<int64_t>(radius) * radius;
  std::vector<ChunkCoord> unloaded;
  for (auto it = visible_.begin(); it != visible_.end();) {
    if (distance2(it->first) > r2 || (keep && !keep(it->first))) {
      if (it->second.sent) unloaded.push_back(it->first);
      if (!it->second.version) --unresolved_;
      it = visible_.erase(it);
    } else {
      ++it;
    }
  }
  for (int dz = -radius; dz <= radius; ++dz)
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        if (dx * dx + dy * dy + dz * dz <= r2 && (!keep || keep(center.offset(dx, dy, dz))) &&
            visible_.try_emplace(center.offset(dx, dy, dz)).second) {
          ++unresolved_;
        }
      }
  view_announced_ = false;
  updates_.clear();  // re-ordered around the new centre
  fresh_.clear();
  waiting_.clear();
  deferred_.clear();
  for (auto& [c, held] : visible_) {
    held.queued = true;
    held.deferred = false;
    held.waiting = false;
    (held.version || held.resync ? updates_ : fresh_).push_back({distance2(c), c});
  }
  std::make_heap(updates_.begin(), updates_.end(), std::greater<>());
  std::make_heap(fresh_.begin(), fresh_.end(), std::greater<>());
  return unloaded;
}

void SendScheduler::queue(ChunkCoord c, Held& held) {
  held.queued = true;
  held.waiting = false;  // marked: it has been published since
  auto& heap = held.version || held.resync ? updates_ : fresh_;
  heap.push_back({distance2(c), c});
  std::push_heap(heap.begin(), heap.end(), std::greater<>());
}

void SendScheduler::mark_stale(ChunkCoord c) {
  // Most published chunks are outside this view: the distance says so without a lookup.
  if (distance2(c) > static_cast<int64_t>(radius_) * radius_) return;
  auto it = visible_.find(c);
  if (it == visible_.end() || it->second.queued) return;
  queue(c, it->second);
}

bool SendScheduler::resync(ChunkCoord c) {
  if (distance2(c) > static_cast<int64_t>(radius_) * radius_) return false;
  auto it = visible_.find(c);
  if (it == visible_.end()) return false;
  Held& held = it->second;
  if (held.version) ++unresolved_;
  held.version = nullptr;
  held.sent = false;  // the client holds nothing of it now: no ChunkUnload is due either
  held.resync = true;
  if (!held.queued) queue(c, held);
  return true;
}

std::optional<SendScheduler::ViewComplete> SendScheduler::take_view_complete() {
  if (view_announced_ || unresolved_ > 0 || radius_ < 0) return std::nullopt;
  view_announced_ = true;
  ViewComplete counts;
  for (const auto& entry : visible_) ++(entry.second.sent ? counts.sent : counts.empty);
  return counts;
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

int64_t SendScheduler::nearest_waiting() {
  while (!waiting_.empty()) {
    const Entry& top = waiting_.front();
    auto it = visible_.find(top.second);
    if (it != visible_.end() && it->second.waiting) return top.first;
    std::pop_heap(waiting_.begin(), waiting_.end(), std::greater<>());
    waiting_.pop_back();
  }
  return INT64_MAX;
}

std::optional<SendScheduler::Send> SendScheduler::next(const Lookup& lookup,
                                                       uint64_t first_unsendable) {
  if (auto send = take(updates_, false, lookup, first_unsendable)) return send;
  return take(fresh_, true, lookup, first_unsendable);
}

std::optional<SendScheduler::Send> SendScheduler::take(std::vector<Entry>& heap, bool fresh,
                                                       const Lookup& lookup,
                                                       uint64_t first_unsendable) {
  while (!heap.empty()) {
    if (fresh && heap.front().first > nearest_waiting()) return std::nullopt;  // a nearer one loads
    std::pop_heap(heap.begin(), heap.end(), std::greater<>());
    const ChunkCoord c = heap.back().second;
    heap.pop_back();
    auto it = visible_.find(c);
    if (it == visible_.end()) continue;
    Held& held = it->second;
    held.queued = false;
    pipeline::MeshVersionPtr current = lookup(c);
    if (!current) {
      if (!held.version && !held.waiting) {
        held.waiting = true;
        waiting_.push_back({distance2(c), c});
        std::push_heap(waiting_.begin(), waiting_.end(), std::greater<>());
      }
      continue;
    }
    held.waiting = false;
    if (held.version && held.version->version >= current->version) continue;
    if (current->version >= first_unsendable) {
      if (!held.deferred) {
        held.deferred = true;
        deferred_.push_back(c);
      }
      continue;
    }
    if (!held.version) --unresolved_;
    if (!held.version && current->triangles == 0 && !held.resync) {
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
  updates_.clear();
  fresh_.clear();
  waiting_.clear();
  deferred_.clear();
  radius_ = -1;
  unresolved_ = 0;
  view_announced_ = true;
}

}  // namespace vox::net
