// A fixed-bucket histogram of durations in seconds that any thread may observe without a
// lock (relaxed atomics); the metrics endpoint reads a snapshot. Bounds follow the
// Prometheus convention: bucket i counts observations <= bounds[i], plus +Inf.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

namespace vox::net {

class LatencyHistogram {
 public:
  // 0.5 ms .. 30 s: what an edit, a batch or a re-mesh can take.
  static constexpr std::array<double, 16> kBounds{
      0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 20, 30};

  void observe(double seconds) {  // any thread
    size_t i = 0;
    while (i < kBounds.size() && seconds > kBounds[i]) ++i;
    buckets_[i].fetch_add(1, std::memory_order_relaxed);
    sum_ns_.fetch_add(static_cast<uint64_t>(seconds * 1e9), std::memory_order_relaxed);
  }

  struct Snapshot {
    std::vector<uint64_t> cumulative;  // per bound, then +Inf (= count)
    double sum = 0;
  };
  Snapshot snapshot() const {  // any thread
    Snapshot s;
    uint64_t running = 0;
    for (const auto& b : buckets_) {
      running += b.load(std::memory_order_relaxed);
      s.cumulative.push_back(running);
    }
    s.sum = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / 1e9;
    return s;
  }

 private:
  std::array<std::atomic<uint64_t>, kBounds.size() + 1> buckets_{};
  std::atomic<uint64_t> sum_ns_{0};
};

}  // namespace vox::net
