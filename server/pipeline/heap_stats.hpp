// What the process holds beyond what its parts account: the allocator's own counters
// (jemalloc's, read through mallctl when voxeld links it; tests and sanitizer builds do not,
// and get none) and the resident set. Any thread; each read takes the allocator's stats
// lock briefly (a few microseconds), so callers read about once a second.
#pragma once

#include <cstddef>
#include <optional>

namespace vox::pipeline {

struct HeapStats {
  size_t allocated = 0;  // bytes the program holds
  size_t active = 0;     // in pages with a live allocation (allocated + what size classes waste)
  size_t resident = 0;   // the allocator's resident pages, freed ones not yet returned included
};
// nullopt without jemalloc.
std::optional<HeapStats> read_heap_stats();

// The process's resident set size (/proc/self/statm); 0 when unknown.
size_t process_resident_bytes();

}  // namespace vox::pipeline
