// An indexed triangle mesh of one chunk (or of a whole volume, for offline meshing).
// Positions are chunk-local in voxel units (0..32 inclusive); add the chunk origin
// (32 * chunk coordinate) for world space. Normals are unit length and point to air.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace vox::mesh {

// Blocks of at least kLargeBlockBytes (whole-volume buffers of offline meshing) are mapped
// directly, asked for transparent huge pages and populated in one call: first touching
// them a 4 KiB page at a time cost a quarter of `voxel-cli mesh`. Any thread.
inline constexpr size_t kLargeBlockBytes = size_t{4} << 20;
void* allocate_large_block(size_t bytes);  // throws std::bad_alloc
void free_large_block(void* p, size_t bytes) noexcept;

// resize() on these leaves new elements uninitialised, so the mesher can size an output
// buffer and then write it without paying for zero-filling first.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  using std::allocator<T>::allocator;
  T* allocate(size_t n) {
    if (n >= kLargeBlockBytes / sizeof(T))
      return static_cast<T*>(allocate_large_block(n * sizeof(T)));
    return std::allocator<T>::allocate(n);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n >= kLargeBlockBytes / sizeof(T)) return free_large_block(p, n * sizeof(T));
    std::allocator<T>::deallocate(p, n);
  }
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
template <class T>
using Buffer = std::vector<T, DefaultInitAllocator<T>>;

struct Vec3f {
  float x = 0, y = 0, z = 0;
  friend constexpr bool operator==(const Vec3f&, const Vec3f&) = default;
};

struct ChunkMesh {
  Buffer<Vec3f> positions;
  Buffer<Vec3f> normals;
  Buffer<uint8_t> materials;  // per vertex: material of the edge's solid end
  Buffer<uint32_t> indices;   // 3 per triangle, counter-clockwise seen from the air side

  size_t vertex_count() const { return positions.size(); }
  size_t triangle_count() const { return indices.size() / 3; }
  bool empty() const { return indices.empty(); }
  // Empties the mesh, keeping capacity so that the next mesh reuses the buffers.
  void clear() {
    positions.clear();
    normals.clear();
    materials.clear();
    indices.clear();
  }
};

}  // namespace vox::mesh
