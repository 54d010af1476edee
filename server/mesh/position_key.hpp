// A vertex position as a key for welding: the exact bits of its coordinates. Vertices on
// chunk faces are bit-identical to their twins in the neighbouring chunk (see
// mesh_welder.hpp), so equal positions have equal keys and no tolerance is needed.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::mesh {

struct PositionKey {
  uint32_t x, y, z;
  bool operator==(const PositionKey&) const = default;
};

inline PositionKey position_key(const Vec3f& p) {
  return {std::bit_cast<uint32_t>(p.x), std::bit_cast<uint32_t>(p.y), std::bit_cast<uint32_t>(p.z)};
}

// Mixes all three coordinates into the low bits (the welder's open-addressing table masks
// them).
inline uint32_t hash_of(const PositionKey& k) {
  uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
  h ^= (h >> 32) ^ (k.y * 0xC2B2AE3D27D4EB4Full);
  h ^= (h >> 29) ^ (k.z * 0x165667B19E3779F9ull);
  return static_cast<uint32_t>(h ^ (h >> 31));
}

struct PositionKeyHash {
  size_t operator()(const PositionKey& k) const { return hash_of(k); }
};

}  // namespace vox::mesh
