#include "server/world/grid_cache.hpp"

#include <algorithm>
#include <cstdint>

namespace vox::world {
namespace {

size_t count_of(const GridCache::Key& k) {
  return static_cast<size_t>(k.n[0]) * static_cast<size_t>(k.n[1]) * static_cast<size_t>(k.n[2]);
}

static_assert(sizeof(GridCache::Run) == 4);

constexpr size_t kEntryOverhead = 128;  // map node, list node, vector header

size_t size_of(const std::vector<GridCache::Run>& runs) {
  return runs.size() * sizeof(GridCache::Run) + kEntryOverhead;
}

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
  for (const Run& r : *grid)
    out = std::fill_n(out, size_t{r.more} + 1, Sample{r.density, r.material});
  return true;
}

void GridCache::put(const Key& k, const Sample* samples) {
  const size_t count = count_of(k);
  if (count == 0) return;
  auto runs = std::make_shared<std::vector<Run>>();
  runs->push_back({samples[0].density, samples[0].material, 0});
  for (size_t i = 1; i < count; ++i) {
    Run& last = runs->back();
    if (samples[i].density == last.density && samples[i].material == last.material &&
        last.more < UINT8_MAX)
      ++last.more;
    else
      runs->push_back({samples[i].density, samples[i].material, 0});
  }
  runs->shrink_to_fit();
  const size_t size = size_of(*runs);
  if (size > max_bytes_ / 4) return;  // one grid never takes most of the cache
  Grid grid = std::move(runs);
  std::vector<Grid> dropped;  // freed outside the lock
  std::lock_guard lock(mutex_);
  if (grids_.count(k)) return;  // another thread put it meanwhile
  order_.push_front(k);
  grids_.emplace(k, Entry{std::move(grid), order_.begin()});
  size_t bytes = bytes_.load(std::memory_order_relaxed) + size;
  while (bytes > max_bytes_ && !order_.empty()) {
    const auto last = grids_.find(order_.back());
    bytes -= size_of(*last->second.grid);
    dropped.push_back(std::move(last->second.grid));
    grids_.erase(last);
    order_.pop_back();
  }
  bytes_.store(bytes, std::memory_order_relaxed);
}

}  // namespace vox::world
