#include "server/world/grid_cache.hpp"

#include <algorithm>

namespace vox::world {
namespace {

size_t count_of(const GridCache::Key& k) {
  return static_cast<size_t>(k.n[0]) * static_cast<size_t>(k.n[1]) * static_cast<size_t>(k.n[2]);
}

constexpr size_t kEntryOverhead = 128;  // map node, list node, vector header

}  // namespace

size_t GridCache::KeyHash::operator()(const Key& k) const {
  uint64_t h = 0xCBF29CE484222325ull;
  for (const int32_t v : {k.origin[0], k.origin[1], k.origin[2], k.step, k.n[0], k.n[1], k.n[2]})
    h = (h ^ static_cast<uint32_t>(v)) * 0x100000001B3ull;
  return static_cast<size_t>(h ^ (h >> 31));
}

bool GridCache::get(const Key& k, Sample* out) {
  Grid grid;
  {
    std::lock_guard lock(mutex_);
    const auto it = grids_.find(k);
    if (it == grids_.end()) return false;
    order_.splice(order_.begin(), order_, it->second.at);
    grid = it->second.grid;
  }
  std::copy(grid->begin(), grid->end(), out);
  return true;
}

void GridCache::put(const Key& k, const Sample* samples) {
  const size_t count = count_of(k);
  const size_t size = count * sizeof(Sample) + kEntryOverhead;
  if (size > max_bytes_ / 4) return;  // one grid never takes most of the cache
  auto grid = std::make_shared<const std::vector<Sample>>(samples, samples + count);
  std::vector<Grid> dropped;  // freed outside the lock
  std::lock_guard lock(mutex_);
  if (grids_.count(k)) return;  // another thread put it meanwhile
  order_.push_front(k);
  grids_.emplace(k, Entry{std::move(grid), order_.begin()});
  size_t bytes = bytes_.load(std::memory_order_relaxed) + size;
  while (bytes > max_bytes_ && !order_.empty()) {
    const auto last = grids_.find(order_.back());
    bytes -= count_of(last->first) * sizeof(Sample) + kEntryOverhead;
    dropped.push_back(std::move(last->second.grid));
    grids_.erase(last);
    order_.pop_back();
  }
  bytes_.store(bytes, std::memory_order_relaxed);
}

}  // namespace vox::world
