// Counters the sessions bump and the server's periodic stats line reads. Any thread.
#pragma once

#include <atomic>
#include <cstdint>

namespace vox::net {

struct ServerCounters {
  std::atomic<uint64_t> players{0};
  std::atomic<uint64_t> edits{0};
  std::atomic<uint64_t> meshes_sent{0};
  std::atomic<uint64_t> deltas_sent{0};
  std::atomic<uint64_t> bytes_sent{0};
  std::atomic<uint64_t> disconnects{0};
};

}  // namespace vox::net
