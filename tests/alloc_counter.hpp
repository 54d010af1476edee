// Counts global operator new calls made by the current thread (tests of "no allocation
// once warm").
#pragma once

#include <cstddef>

namespace vox::test {
size_t allocations_on_this_thread();
}
