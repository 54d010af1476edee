#include "server/world/overlay_sampler.hpp"

#include <algorithm>
#include <vector>

namespace vox::world {
namespace {

// The grid indices i (0 <= i < n) with lo <= origin + step * i <= hi.
std::pair<int, int> indices_within(int64_t origin, int64_t step, int n, int64_t lo, int64_t hi) {
  const int64_t first = lo <= origin ? 0 : (lo - origin + step - 1) / step;
  const int64_t last = hi < origin ? -1 : (hi - origin) / step;
  return {static_cast<int>(std::max<int64_t>(first, 0)),
          static_cast<int>(std::min<int64_t>(last, n - 1))};
}

}  // namespace

void OverlaySampler::sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                                 const std::array<int, 3>& n, Sample* out) const {
  thread_local std::vector<float> lattice;  // a vector: only its three pointers are TLS
  const GridCache::Key key{origin, step, n};
  if (!cache_ || !cache_->get(key, out)) {
    generator_.sample_grid(origin, step, n, out, lattice);
    // Sky and deep rock cost no noise: keep the cache for grids that did.
    if (cache_ && !generator_.grid_is_uniform(origin[1], step, n[1])) cache_->put(key, out);
  }
  if (modified_.empty()) return;
  // The chunks the grid's box touches; the modified ones among them, found from whichever
  // is smaller: the box or the set.
  ChunkCoord lo, hi;
  int64_t box = 1;
  for (int a = 0; a < 3; ++a) {
    const int32_t first = floor_div(origin[a], kChunkSize);
    const int32_t last =
        floor_div(static_cast<int32_t>(origin[a] + int64_t{step} * (n[a] - 1)), kChunkSize);
    (&lo.x)[a] = first;
    (&hi.x)[a] = last;
    box *= int64_t{last} - first + 1;
  }
  if (box <= static_cast<int64_t>(modified_.size())) {
    for_each_chunk_in(lo, hi, [&](ChunkCoord c) {
      if (modified_.contains(c)) overlay(c, origin, step, n, out);
    });
    return;
  }
  for (const ChunkCoord c : modified_) {
    if (c.x >= lo.x && c.x <= hi.x && c.y >= lo.y && c.y <= hi.y && c.z >= lo.z && c.z <= hi.z)
      overlay(c, origin, step, n, out);
  }
}

void OverlaySampler::overlay(ChunkCoord c, const std::array<int32_t, 3>& origin, int32_t step,
                             const std::array<int, 3>& n, Sample* out) const {
  std::array<std::pair<int, int>, 3> range;
  for (int a = 0; a < 3; ++a) {
    const int64_t lo = int64_t{(&c.x)[a]} * kChunkSize;
    range[a] = indices_within(origin[a], step, n[a], lo, lo + kChunkSize - 1);
    if (range[a].first > range[a].second) return;  // no grid point in the chunk
  }
  const Chunk& chunk = lookup_(c);
  const Density* density = chunk.densities();
  const Material* material = chunk.materials();
  const int32_t base[3] = {origin[0] - c.x * kChunkSize, origin[1] - c.y * kChunkSize,
                           origin[2] - c.z * kChunkSize};
  for (int k = range[2].first; k <= range[2].second; ++k)
    for (int j = range[1].first; j <= range[1].second; ++j) {
      Sample* row = out + n[0] * (j + static_cast<size_t>(n[1]) * k);
      if (!density) {  // a uniform chunk
        std::fill(row + range[0].first, row + range[0].second + 1, chunk.uniform_value());
        continue;
      }
      const int line = Chunk::index(0, base[1] + step * j, base[2] + step * k);
      for (int i = range[0].first; i <= range[0].second; ++i) {
        const int at = line + base[0] + step * i;
        row[i] = {density[at], material[at]};
      }
    }
}

}  // namespace vox::world
