// Counts global operator new calls, and the bytes they ask for, made by the current thread
// (tests of "no allocation once warm" and of sizes checked before allocating).
#pragma once

#include <cstddef>

namespace vox::test {
size_t allocations_on_this_thread();
size_t bytes_allocated_on_this_thread();
}  // namespace vox::test
