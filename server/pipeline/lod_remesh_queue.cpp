#include "server/pipeline/lod_remesh_queue.hpp"

#include <algorithm>
#include <stdexcept>

namespace vox::pipeline {
namespace {

// floor(a / b) and ceil(a / b) for b > 0.
int64_t floor_div64(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int64_t ceil_div64(int64_t a, int64_t b) { return -floor_div64(-a, b); }

}  // namespace

LodRemeshQueue::LodRemeshQueue(int levels, Clock::duration interval, size_t max_pending)
    : levels_(levels), interval_(interval), max_pending_(max_pending) {
  if (levels < 1 || levels > 20 || interval.count() < 0 || max_pending == 0)
    throw std::invalid_argument("LodRemeshQueue: bad settings");
}

void LodRemeshQueue::affected(const world::VoxelBox& changed,
                              std::vector<world::LodChunk>& out) const {
  out.clear();
  for (int level = 1; level < levels_; ++level) {
    const int64_t step = int64_t{1} << level, side = world::kChunkSize * step;
    // Chunk c samples voxels [side * c - step, side * c + 33 * step].
    std::array<int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = ceil_div64(int64_t{changed.lo[a]} - 33 * step, side);
      hi[a] = floor_div64(int64_t{changed.hi[a]} + step, side);
    }
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
      for (int64_t y = lo[1]; y <= hi[1]; ++y)
        for (int64_t x = lo[0]; x <= hi[0]; ++x)
          out.push_back(
              {level, {static_cast<int32_t>(x), static_cast<int32_t>(y), static_cast<int32_t>(z)}});
  }
}

void LodRemeshQueue::mark(const world::VoxelBox& changed, Clock::time_point now,
                          const std::function<bool(const world::LodChunk&)>& viewed) {
  std::vector<world::LodChunk> chunks;
  affected(changed, chunks);
  for (const world::LodChunk& c : chunks) {
    if (!viewed(c) || pending_.count(c)) continue;
    const Clock::time_point due = std::max(now, due_time(c));
    pending_.emplace(c, due);
    by_due_.insert({due, c});
  }
  while (pending_.size() > max_pending_) {  // the coarsest go first
    const auto last = std::prev(pending_.end());
    by_due_.erase({last->second, last->first});
    dropped_chunks_.push_back(last->first);
    pending_.erase(last);
    ++dropped_;
  }
  if (last_taken_.size() > 2 * max_pending_) forget_old_takes(now);
}

LodRemeshQueue::Clock::duration LodRemeshQueue::interval(int level) const {
  return interval_ * std::min(kMaxIntervalFactor, 1 << std::clamp(level - 1, 0, 16));
}

LodRemeshQueue::Clock::time_point LodRemeshQueue::due_time(const world::LodChunk& c) const {
  const auto it = last_taken_.find(c);
  return it == last_taken_.end() ? Clock::time_point{} : it->second + interval(c.level);
}

std::vector<world::LodChunk> LodRemeshQueue::take_due(Clock::time_point now, size_t max) {
  std::vector<world::LodChunk> out;
  while (!by_due_.empty() && out.size() < max && by_due_.begin()->first <= now) {
    const world::LodChunk c = by_due_.begin()->second;
    by_due_.erase(by_due_.begin());
    pending_.erase(c);
    out.push_back(c);
    last_taken_[c] = now;
  }
  return out;
}

std::optional<LodRemeshQueue::Clock::time_point> LodRemeshQueue::next_due() const {
  if (by_due_.empty()) return std::nullopt;
  return by_due_.begin()->first;
}

std::vector<world::LodChunk> LodRemeshQueue::take_dropped() {
  std::vector<world::LodChunk> out;
  out.swap(dropped_chunks_);
  return out;
}

void LodRemeshQueue::forget(const world::LodChunk& c) {
  if (const auto it = pending_.find(c); it != pending_.end()) {
    by_due_.erase({it->second, c});
    pending_.erase(it);
  }
  last_taken_.erase(c);
}

void LodRemeshQueue::forget_old_takes(Clock::time_point now) {
  for (auto it = last_taken_.begin(); it != last_taken_.end();) {
    if (it->second + interval(it->first.level) <= now)
      it = last_taken_.erase(it);
    else
      ++it;
  }
}

}  // namespace vox::pipeline
