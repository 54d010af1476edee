#include "server/pipeline/memory_keeper.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdint>

namespace vox::pipeline {

std::optional<MemoryKeeper::Pass> MemoryKeeper::due(Clock::time_point now, size_t resident,
                                                    size_t other) const {
  const bool periodic = now - last_ > evict_after_ / 4;
  const bool pressure = budget_.should_evict(resident) &&
                        (last_freed_ || resident > resident_after_ || now - last_ > kPressureRetry);
  if (!periodic && !pressure) return std::nullopt;
  // The periodic pass drops only idle chunks; under pressure, down to the target.
  return Pass{.idle = evict_after_,
              .min_age = std::min(min_age_, evict_after_),
              .target_bytes = pressure ? budget_.evict_target(other) : SIZE_MAX,
              .max_scan = periodic ? SIZE_MAX : kPressureScan};
}

void MemoryKeeper::evicted(Clock::time_point now, size_t dropped, size_t resident) {
  last_ = now;
  last_freed_ = dropped > 0;
  resident_after_ = resident;
}

std::optional<MemoryKeeper::Pass> MemoryKeeper::for_edits(size_t need, size_t other) {
  if (evicted_for_edits_) return std::nullopt;
  evicted_for_edits_ = true;
  const size_t target = budget_.evict_target(other);
  // Chunks this batch used (loaded or touched: last used now) always stay.
  return Pass{.idle = evict_after_,
              .min_age = std::max<std::chrono::milliseconds>(std::min(min_age_, evict_after_),
                                                             std::chrono::milliseconds(1)),
              .target_bytes = target > need ? target - need : 0,
              .max_scan = kPressureScan};
}

bool MemoryKeeper::update_blocked(size_t total) {
  const bool blocked = budget_.load_work(total, 1) == 0;
  if (blocked == blocked_.load(std::memory_order_relaxed)) return false;
  blocked_.store(blocked, std::memory_order_relaxed);
  const size_t max = budget_.max_bytes();
  if (blocked) {
    spdlog::warn(
        "memory budget: {} MiB accounted of {} MiB (--max-memory) and nothing left to evict; "
        "new chunk loads wait",
        total >> 20, max >> 20);
  } else {
    spdlog::info("memory budget: {} MiB accounted of {} MiB; loads resume", total >> 20, max >> 20);
  }
  return true;
}

std::chrono::milliseconds MemoryKeeper::next_look(bool loads_queued) const {
  if (!loads_queued) return std::chrono::duration_cast<std::chrono::milliseconds>(evict_after_ / 4);
  return loads_blocked() ? kPressureRetry : kBudgetRetry;
}

}  // namespace vox::pipeline
