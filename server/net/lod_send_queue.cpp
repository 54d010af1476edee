#include "server/net/lod_send_queue.hpp"

#include <algorithm>

namespace vox::net {

using world::LodChunk;

bool LodSendQueue::resolved(const Held& h) { return h.version && h.version_seams == h.seams; }

void LodSendQueue::queue(const LodChunk& c, Held& h) {
  if (h.queued) return;
  h.queued = true;
  heap_.push_back({{h.distance, c.level}, c});
  std::push_heap(heap_.begin(), heap_.end(), std::greater<>());
}

std::vector<LodChunk> LodSendQueue::apply(const world::LodViewChange& change,
                                          const std::array<double, 3>& eye) {
  eye_ = eye;
  std::vector<LodChunk> unloaded;
  for (const LodChunk& c : change.unload) {
    const auto it = chunks_.find(c);
    if (it == chunks_.end()) continue;
    if (it->second.sent) unloaded.push_back(c);
    if (!resolved(it->second)) --unresolved_;
    chunks_.erase(it);
  }
  for (const auto& [c, seams] : change.send) {
    if (c.level < 1) continue;  // level 0 goes through the SendScheduler
    auto [it, inserted] = chunks_.try_emplace(c);
    const bool was = !inserted && resolved(it->second);
    it->second.seams = world::normalized(seams);
    // New, or new seams: unresolved until the mesh with these seams is recorded.
    if (inserted || (was && !resolved(it->second))) ++unresolved_;
    if (!inserted && !was && resolved(it->second)) --unresolved_;  // back to the held seams
  }
  // Chunks neither queued nor changed wait for mark_stale(): only the others are queued
  // again, at their new distances.
  heap_.clear();
  for (auto& [c, h] : chunks_) {
    h.distance = world::distance_to(c, eye_);
    if (!h.queued) continue;
    h.queued = false;
    queue(c, h);
  }
  for (const auto& [c, seams] : change.send) {
    if (const auto it = chunks_.find(c); it != chunks_.end()) queue(c, it->second);
  }
  announced_ = false;
  return unloaded;
}

void LodSendQueue::mark_stale(const pipeline::LodKey& k) {
  const auto it = chunks_.find(k.chunk);
  if (it == chunks_.end() || !(it->second.seams == k.seams)) return;
  queue(k.chunk, it->second);
}

bool LodSendQueue::resync(const LodChunk& c) {
  const auto it = chunks_.find(c);
  if (it == chunks_.end()) return false;
  Held& h = it->second;
  if (resolved(h)) ++unresolved_;
  h.version = nullptr;
  h.sent = false;
  h.wire_version = 0;
  h.resync = true;
  queue(c, h);
  return true;
}

std::vector<pipeline::LodKey> LodSendQueue::wants() const {
  std::vector<std::pair<double, pipeline::LodKey>> order;
  order.reserve(chunks_.size());
  for (const auto& [c, h] : chunks_) order.push_back({h.distance, {c, h.seams}});
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second.chunk < b.second.chunk;
  });
  std::vector<pipeline::LodKey> keys;
  keys.reserve(order.size());
  for (const auto& [d, k] : order) keys.push_back(k);
  return keys;
}

std::optional<LodSendQueue::Send> LodSendQueue::next(const Lookup& lookup) {
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), std::greater<>());
    const LodChunk c = heap_.back().second;
    heap_.pop_back();
    const auto it = chunks_.find(c);
    if (it == chunks_.end() || !it->second.queued) continue;
    Held& h = it->second;
    h.queued = false;
    pipeline::MeshVersionPtr v = lookup({c, h.seams});
    if (!v || v == h.version) continue;  // not meshed yet (marked when it is), or held
    if (!resolved(h)) --unresolved_;
    const pipeline::MeshVersionPtr base = h.sent ? h.version : nullptr;
    h.version = v;
    h.version_seams = h.seams;
    if (!h.sent && !h.resync && v->triangles == 0) continue;  // nothing to show yet
    Send s{c, std::move(v), base, next_wire_version_++, base ? h.wire_version : 0};
    h.wire_version = s.wire_version;
    h.sent = true;
    h.resync = false;
    return s;
  }
  return std::nullopt;
}

std::optional<LodSendQueue::Complete> LodSendQueue::take_complete() {
  if (announced_ || unresolved_ > 0) return std::nullopt;
  announced_ = true;
  Complete done;
  for (const auto& [c, h] : chunks_) ++(h.sent ? done.sent : done.empty);
  return done;
}

void LodSendQueue::clear() {
  chunks_.clear();
  heap_.clear();
  unresolved_ = 0;
  announced_ = true;
}

}  // namespace vox::net
