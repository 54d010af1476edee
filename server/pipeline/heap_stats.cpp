#include "server/pipeline/heap_stats.hpp"

#include <unistd.h>

#include <cstdint>
#include <fstream>

// jemalloc's control interface, when the executable links it (voxeld does); weak, so that
// programs with another allocator link and see a null pointer.
extern "C" int mallctl(const char* name, void* oldp, size_t* oldlenp, void* newp, size_t newlen)
    __attribute__((weak));

namespace vox::pipeline {

std::optional<HeapStats> read_heap_stats() {
  if (mallctl == nullptr) return std::nullopt;
  uint64_t epoch = 1;
  size_t len = sizeof(epoch);
  // The counters are a snapshot taken when the epoch advances.
  if (mallctl("epoch", &epoch, &len, &epoch, len) != 0) return std::nullopt;
  HeapStats s;
  const auto read = [](const char* name, size_t& out) {
    size_t size = sizeof(out);
    return mallctl(name, &out, &size, nullptr, 0) == 0;
  };
  if (!read("stats.allocated", s.allocated) || !read("stats.active", s.active) ||
      !read("stats.resident", s.resident))
    return std::nullopt;
  return s;
}

size_t process_resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  size_t pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0;
  return pages_resident * static_cast<size_t>(::sysconf(_SC_PAGE_SIZE));
}

}  // namespace vox::pipeline
