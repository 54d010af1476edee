#include "server/world/lod_view.hpp"

#include <algorithm>

namespace vox::world {

LodViewChange LodView::update(const std::array<double, 3>& eye) {
  LodViewChange change;
  // The same leaves: the same seams too (the inner nodes are the leaves' ancestors).
  if (!layout_.update(eye) && !layout_.chunks().empty()) return change;
  const LodSeamsMap& now = layout_.all_seams();
  for (const auto& [c, seams] : now) {
    const auto held = held_.find(c);
    if (held == held_.end() || held->second != seams) change.send.emplace_back(c, seams);
  }
  for (const auto& [c, seams] : held_)
    if (!now.contains(c)) change.unload.push_back(c);
  std::sort(change.unload.begin(), change.unload.end());
  // Nearest first, finer first between equals (then by coordinate: a stable order).
  std::vector<std::pair<double, size_t>> order;
  order.reserve(change.send.size());
  for (size_t i = 0; i < change.send.size(); ++i)
    order.emplace_back(distance_to(change.send[i].first, eye), i);
  std::sort(order.begin(), order.end(), [&](const auto& a, const auto& b) {
    if (a.first != b.first) return a.first < b.first;
    return change.send[a.second].first < change.send[b.second].first;
  });
  std::vector<std::pair<LodChunk, LodSeams>> sorted;
  sorted.reserve(order.size());
  for (const auto& [d, i] : order) sorted.push_back(change.send[i]);
  change.send = std::move(sorted);
  held_ = now;
  return change;
}

}  // namespace vox::world
