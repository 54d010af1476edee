// When the pipeline evicts, over time (MemoryBudget says how much): a periodic pass drops
// idle chunks every evict_after / 4; under pressure a pass runs after every batch while
// eviction frees something or the world grew since, and at most every kPressureRetry when
// it freed nothing and nothing came (everything is in use: the scan is not free). Edits
// that need room get one pass per batch. It also says whether loads must wait. Pure: the
// pipeline gives it the time and the bytes, and does the evicting. Pipeline thread, but
// loads_blocked() and the other bytes (any thread).
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "server/pipeline/memory_budget.hpp"

namespace vox::pipeline {

class MemoryKeeper {
 public:
  using Clock = std::chrono::steady_clock;
  // Chunks one eviction pass under pressure looks at (about 1 ms): a batch never stalls on
  // a scan of the whole world.
  static constexpr size_t kPressureScan = 4096;
  // While over the budget, eviction is retried at most this often.
  static constexpr auto kPressureRetry = std::chrono::milliseconds(250);
  // Loads waiting only for their owners' load budgets are looked at again this often.
  static constexpr auto kBudgetRetry = std::chrono::milliseconds(20);

  // `evict_after`: unused this long, a saved chunk goes; `min_age`: used more recently, it
  // stays even over the budget.
  MemoryKeeper(MemoryBudget budget, std::chrono::milliseconds evict_after,
               std::chrono::milliseconds min_age, Clock::time_point now)
      : budget_(budget), evict_after_(evict_after), min_age_(min_age), last_(now) {}

  const MemoryBudget& budget() const { return budget_; }

  // An eviction pass (WorldState::evict's arguments but the world's).
  struct Pass {
    std::chrono::milliseconds idle, min_age;
    size_t target_bytes;  // what the chunks and meshes may keep (SIZE_MAX: idle ones only)
    size_t max_scan;
  };
  // The pass due now, if any; `resident`: the bytes accounted now, `other`: those that
  // cannot be evicted (sessions').
  std::optional<Pass> due(Clock::time_point now, size_t resident, size_t other) const;
  // The pass ran: it dropped `dropped` chunks, leaving `resident` bytes.
  void evicted(Clock::time_point now, size_t dropped, size_t resident);

  // An edit of the batch needs `need` bytes more than fit: the pass to make room, once per
  // batch (none: refuse it).
  std::optional<Pass> for_edits(size_t need, size_t other);
  void new_batch() { evicted_for_edits_ = false; }

  // Whether loads must wait at `total` accounted bytes (no room even once the terrain on
  // its way has landed); true when that changed (and logged).
  bool update_blocked(size_t total);
  bool loads_blocked() const { return blocked_.load(std::memory_order_relaxed); }  // any thread
  // Bytes counted in the budget that eviction cannot free (any thread): sessions' state,
  // and the heap the allocator holds beyond every part's account (structures no part
  // counts, what its size classes waste). Without the second, the accounted bytes stayed
  // under the budget while the process's resident set went 8 % past it.
  void set_session_bytes(size_t bytes) { session_bytes_.store(bytes, std::memory_order_relaxed); }
  size_t session_bytes() const { return session_bytes_.load(std::memory_order_relaxed); }
  size_t unaccounted_bytes() const { return unaccounted_bytes_.load(std::memory_order_relaxed); }
  size_t other_bytes() const { return session_bytes() + unaccounted_bytes(); }
  // The allocator's heap is looked at this often (pipeline thread): heap_due() says when,
  // and heap_measured() takes `active` (the allocator's pages in use) against `parts` (what
  // the parts account, sessions and terrain on its way included), setting the unaccounted
  // bytes to the difference (none when the parts account more).
  static constexpr auto kHeapLook = std::chrono::seconds(1);
  bool heap_due(Clock::time_point now) const { return now - heap_looked_ >= kHeapLook; }
  void heap_measured(Clock::time_point now, size_t active, size_t parts) {
    heap_looked_ = now;
    unaccounted_bytes_.store(active > parts ? active - parts : 0, std::memory_order_relaxed);
  }

  // How long the idle pipeline may sleep before it looks again: loads waiting for memory
  // retry eviction often (sessions release meshes), loads waiting for their owners'
  // budgets sooner still; with none, the periodic pass.
  std::chrono::milliseconds next_look(bool loads_queued) const;

 private:
  const MemoryBudget budget_;
  const std::chrono::milliseconds evict_after_, min_age_;
  Clock::time_point last_;   // the last pass
  bool last_freed_ = false;  // it dropped something
  size_t resident_after_ = 0;
  Clock::time_point heap_looked_{};
  bool evicted_for_edits_ = false;
  std::atomic<bool> blocked_{false};
  std::atomic<size_t> session_bytes_{0}, unaccounted_bytes_{0};
};

}  // namespace vox::pipeline
