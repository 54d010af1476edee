#include "tests/alloc_counter.hpp"

#include <cstdlib>
#include <new>

namespace {
thread_local size_t g_allocations = 0;
thread_local size_t g_bytes = 0;
}  // namespace

namespace vox::test {
size_t allocations_on_this_thread() { return g_allocations; }
size_t bytes_allocated_on_this_thread() { return g_bytes; }
}  // namespace vox::test

void* operator new(std::size_t size) {
  ++g_allocations;
  g_bytes += size;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
