#include "server/pipeline/world_state.hpp"

#include <algorithm>

#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

WorldState::WorldState(int threads) : arena(arena_concurrency(threads)) {}

void WorldState::load_stored(ChunkCoord c, Clock::time_point now) {
  chunks.insert(c, read_stored(c));
  info[c] = {.modified = true, .last_used = now};
  ++modified_count;
}

size_t WorldState::ensure_loaded(const std::vector<ChunkCoord>& coords,
                                 const world::TerrainGenerator& gen, Clock::time_point now) {
  std::map<std::pair<int32_t, int32_t>, std::vector<int32_t>> columns;
  for (const ChunkCoord& c : coords) {
    auto it = info.find(c);
    if (it != info.end()) {
      it->second.last_used = now;
      continue;
    }
    if (stored.count(c)) {
      load_stored(c, now);
      continue;
    }
    columns[{c.x, c.z}].push_back(c.y);
  }
  if (columns.empty()) return 0;
  std::vector<std::pair<std::pair<int32_t, int32_t>, std::vector<int32_t>>> work(columns.begin(),
                                                                                 columns.end());
  std::vector<std::vector<world::Chunk>> made(work.size());
  std::vector<std::shared_ptr<const world::ColumnHeights>> heights(work.size());
  for (size_t i = 0; i < work.size(); ++i) {
    if (auto it = column_heights.find(work[i].first); it != column_heights.end())
      heights[i] = it->second;
  }
  parallel_for_index(arena, work.size(), [&](size_t i) {
    const auto& [xz, ys] = work[i];
    if (!heights[i])
      heights[i] = std::make_shared<const world::ColumnHeights>(gen.column(xz.first, xz.second));
    for (int32_t y : ys) made[i].push_back(gen.generate({xz.first, y, xz.second}, *heights[i]));
  });
  for (size_t i = 0; i < work.size(); ++i) column_heights.emplace(work[i].first, heights[i]);
  size_t generated = 0;
  for (size_t i = 0; i < work.size(); ++i) {
    for (size_t k = 0; k < work[i].second.size(); ++k) {
      const ChunkCoord c{work[i].first.first, work[i].second[k], work[i].first.second};
      if (info.count(c)) continue;  // listed twice
      chunks.insert(c, std::move(made[i][k]));
      info[c] = {.last_used = now};
      ++generated;
    }
  }
  return generated;
}

void WorldState::pin_neighbourhood(ChunkCoord c) {
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) ++pins[c.offset(dx, dy, dz)];
}

void WorldState::unpin_neighbourhood(ChunkCoord c) {
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        auto it = pins.find(c.offset(dx, dy, dz));
        if (it != pins.end() && --it->second == 0) pins.erase(it);
      }
}

size_t WorldState::evict(MeshStore& meshes, Clock::time_point now, std::chrono::milliseconds idle,
                         std::chrono::milliseconds min_age, size_t target_bytes, size_t max_scan) {
  struct Candidate {
    Clock::time_point used;
    ChunkCoord coord;
  };
  std::vector<Candidate> candidates;
  // Bucket by bucket from the cursor: erasing keeps bucket numbers, and a rehash between
  // calls only makes a window see some chunks twice or later.
  const size_t buckets = info.bucket_count();
  size_t scanned = 0, b = evict_cursor_ % buckets;
  for (size_t seen = 0; seen < buckets && scanned < max_scan; ++seen, b = (b + 1) % buckets) {
    for (auto it = info.begin(b); it != info.end(b); ++it, ++scanned) {
      const auto& [c, chunk_info] = *it;
      if (chunk_info.unsaved || chunk_info.checkpointing || now - chunk_info.last_used < min_age ||
          views.viewed(c) || pins.count(c)) {
        continue;
      }
      const MeshVersionPtr mesh = meshes.get(c);
      if (mesh && mesh.use_count() > 2) continue;  // someone besides the store (and us) holds it
      candidates.push_back({chunk_info.last_used, c});
    }
  }
  evict_cursor_ = b;
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.used != b.used ? a.used < b.used : a.coord < b.coord;
  });
  size_t dropped = 0;
  for (const Candidate& victim : candidates) {
    const bool idle_long = now - victim.used >= idle;
    if (!idle_long && chunks.memory_bytes() + meshes.memory_bytes() <= target_bytes) break;
    auto it = info.find(victim.coord);
    if (it->second.modified && may_evict_modified && !may_evict_modified(victim.coord)) continue;
    chunks.erase(victim.coord);
    modified_count -= it->second.modified ? 1 : 0;
    info.erase(it);
    meshes.erase(victim.coord);
    ++dropped;
  }
  return dropped;
}

}  // namespace vox::pipeline
