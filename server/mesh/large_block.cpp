#include <sys/mman.h>

#include <new>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::mesh {

void* allocate_large_block(size_t bytes) {
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
#if defined(MADV_HUGEPAGE)
  (void)::madvise(p, bytes, MADV_HUGEPAGE);  // advice: without THP, 4 KiB pages
#endif
#if defined(MADV_POPULATE_WRITE)
  (void)::madvise(p, bytes, MADV_POPULATE_WRITE);  // Linux 5.14+; else faulted on first touch
#endif
  return p;
}

void free_large_block(void* p, size_t bytes) noexcept { ::munmap(p, bytes); }

}  // namespace vox::mesh
