// Joins chunk meshes into one world-space mesh. Vertices on chunk faces (a local
// coordinate of exactly 0 or 32) are bit-identical to their twins in the neighbouring
// chunk, so they are merged by exact position; interior vertices are copied as they are.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "mesh/chunk_mesh.hpp"

namespace vox::mesh {

class MeshWelder {
 public:
  void reserve(size_t vertices, size_t indices);
  // `origin` is the chunk's world position (32 * chunk coordinate).
  void add(const ChunkMesh& part, Vec3f origin);
  ChunkMesh take() { return std::move(out_); }

 private:
  struct Key {
    uint32_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    size_t operator()(const Key& k) const noexcept;
  };

  ChunkMesh out_;
  std::unordered_map<Key, uint32_t, KeyHash> face_vertices_;
  std::vector<uint32_t> remap_;
};

}  // namespace vox::mesh
