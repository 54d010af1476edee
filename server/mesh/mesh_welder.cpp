#include "mesh/mesh_welder.hpp"

#include <bit>

#include "world/chunk_coord.hpp"

namespace vox::mesh {

size_t MeshWelder::KeyHash::operator()(const Key& k) const noexcept {
  uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
  h ^= (h >> 32) ^ (k.y * 0xC2B2AE3D27D4EB4Full);
  h ^= (h >> 29) ^ (k.z * 0x165667B19E3779F9ull);
  return static_cast<size_t>(h ^ (h >> 31));
}

void MeshWelder::reserve(size_t vertices, size_t indices) {
  out_.positions.reserve(vertices);
  out_.normals.reserve(vertices);
  out_.materials.reserve(vertices);
  out_.indices.reserve(indices);
}

void MeshWelder::add(const ChunkMesh& part, Vec3f origin) {
  constexpr float kFace = static_cast<float>(world::kChunkSize);
  const auto on_face = [](float c) { return c == 0.0f || c == kFace; };
  remap_.resize(part.vertex_count());
  for (size_t v = 0; v < part.vertex_count(); ++v) {
    const Vec3f l = part.positions[v];
    const Vec3f w{l.x + origin.x, l.y + origin.y, l.z + origin.z};
    if (on_face(l.x) || on_face(l.y) || on_face(l.z)) {
      const Key key{std::bit_cast<uint32_t>(w.x), std::bit_cast<uint32_t>(w.y), std::bit_cast<uint32_t>(w.z)};
      auto [it, inserted] = face_vertices_.try_emplace(key, static_cast<uint32_t>(out_.positions.size()));
      remap_[v] = it->second;
      if (!inserted) continue;
    } else {
      remap_[v] = static_cast<uint32_t>(out_.positions.size());
    }
    out_.positions.push_back(w);
    out_.normals.push_back(part.normals[v]);
    out_.materials.push_back(part.materials[v]);
  }
  for (uint32_t index : part.indices) out_.indices.push_back(remap_[index]);
}

}  // namespace vox::mesh
