// The one place that fans work out over threads. Runs body(i) for every i in [0, n) on
// up to `arena`'s threads (the caller's included) and returns when all are done.
//
// Builds with VOXEL_PARALLEL_STD_THREADS (the ThreadSanitizer build) run the same bodies
// on plain std::threads: Debian's libtbb is not instrumented, so TSan cannot see TBB's
// hand-offs and would flag every result a task passes back; thread create/join it sees.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace vox {

// 0 means "all cores".
inline int arena_concurrency(int threads) {
  return threads > 0 ? threads : tbb::task_arena::automatic;
}

template <class Body>
void parallel_for_index(tbb::task_arena& arena, size_t n, const Body& body) {
  if (n == 0) return;
#ifdef VOXEL_PARALLEL_STD_THREADS
  const size_t workers = std::min(n, static_cast<size_t>(std::max(1, arena.max_concurrency())));
  std::atomic<size_t> next{0};
  auto run = [&] {
    for (size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1)) body(i);
  };
  std::vector<std::thread> threads;
  for (size_t t = 1; t < workers; ++t) threads.emplace_back(run);
  run();
  for (auto& t : threads) t.join();
#else
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) body(i);
    });
  });
#endif
}

}  // namespace vox
