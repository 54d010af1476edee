#include "server/pipeline/terrain_prefetcher.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <map>

#include "server/world/thread_name.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

// Background generation yields to the pipeline's batches (edits) and the sessions: on a
// busy machine it gets about a tenth of a core per thread it competes with.
constexpr int kNice = 10;

}  // namespace

TerrainPrefetcher::TerrainPrefetcher(const world::TerrainGenerator& generator, int threads,
                                     size_t max_chunks, size_t reserve_bytes,
                                     std::function<void()> on_ready)
    : generator_(generator),
      max_chunks_(max_chunks),
      reserve_bytes_(reserve_bytes),
      on_ready_(std::move(on_ready)) {
  for (int i = 0; i < threads; ++i)
    threads_.push_back(named_thread("vox-generate", [this] { work(); }));
}

TerrainPrefetcher::~TerrainPrefetcher() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (auto& t : threads_) t.join();
}

std::vector<ChunkCoord> TerrainPrefetcher::request(std::span<const ChunkCoord> coords) {
  std::vector<ChunkCoord> refused;
  if (threads_.empty()) return {coords.begin(), coords.end()};
  // By column, so each column's surface heights are computed once.
  std::map<std::pair<int32_t, int32_t>, std::vector<int32_t>> columns;
  {
    std::lock_guard lock(mutex_);
    for (const ChunkCoord& c : coords) {
      if (pending_.count(c)) continue;
      if (pending_.size() >= max_chunks_) {
        refused.push_back(c);
        continue;
      }
      pending_.insert(c);
      columns[{c.x, c.z}].push_back(c.y);
    }
    for (auto& [xz, ys] : columns) queue_.push_back({xz.first, xz.second, std::move(ys)});
  }
  if (!columns.empty()) cv_.notify_all();
  return refused;
}

std::vector<std::pair<ChunkCoord, world::Chunk>> TerrainPrefetcher::take_ready() {
  std::lock_guard lock(mutex_);
  for (const auto& [c, chunk] : ready_) pending_.erase(c);
  ready_bytes_ = 0;
  return std::exchange(ready_, {});
}

bool TerrainPrefetcher::pending(ChunkCoord c) const {
  std::lock_guard lock(mutex_);
  return pending_.count(c) > 0;
}

size_t TerrainPrefetcher::pending_count() const {
  std::lock_guard lock(mutex_);
  return pending_.size();
}

size_t TerrainPrefetcher::memory_bytes() const {
  std::lock_guard lock(mutex_);
  return ready_bytes_ + (pending_.size() - ready_.size()) * reserve_bytes_;
}

void TerrainPrefetcher::work() {
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), kNice);  // this thread only
  std::vector<std::pair<ChunkCoord, world::Chunk>> made;
  for (;;) {
    Column column;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      column = std::move(queue_.front());
      queue_.pop_front();
    }
    const world::ColumnHeights heights = generator_.column(column.x, column.z);
    size_t bytes = 0;
    for (int32_t y : column.ys) {
      const ChunkCoord c{column.x, y, column.z};
      made.emplace_back(c, generator_.generate(c, heights));
      bytes += made.back().second.memory_bytes();
    }
    {
      std::lock_guard lock(mutex_);
      for (auto& entry : made) ready_.push_back(std::move(entry));
      ready_bytes_ += bytes;
    }
    made.clear();
    if (on_ready_) on_ready_();
  }
}

}  // namespace vox::pipeline
