// Integer chunk coordinates and the voxel -> chunk mapping (floor division, so negative
// voxel coordinates land in negative chunks).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>

namespace vox::world {

inline constexpr int kChunkSize = 32;  // samples per chunk edge
inline constexpr int kChunkVolume = kChunkSize * kChunkSize * kChunkSize;

constexpr int32_t floor_div(int32_t v, int32_t d) {
  const int32_t q = v / d;
  return (v % d != 0 && ((v < 0) != (d < 0))) ? q - 1 : q;
}
constexpr int32_t floor_mod(int32_t v, int32_t d) { return v - floor_div(v, d) * d; }

struct ChunkCoord {
  int32_t x = 0, y = 0, z = 0;
  friend constexpr bool operator==(const ChunkCoord&, const ChunkCoord&) = default;
  friend constexpr auto operator<=>(const ChunkCoord&, const ChunkCoord&) = default;
  constexpr ChunkCoord offset(int dx, int dy, int dz) const { return {x + dx, y + dy, z + dz}; }
};

constexpr ChunkCoord chunk_of_voxel(int32_t vx, int32_t vy, int32_t vz) {
  return {floor_div(vx, kChunkSize), floor_div(vy, kChunkSize), floor_div(vz, kChunkSize)};
}

// Calls fn(ChunkCoord) for every chunk of the inclusive box lo..hi, x fastest.
template <class Fn>
void for_each_chunk_in(ChunkCoord lo, ChunkCoord hi, Fn&& fn) {
  for (int32_t z = lo.z; z <= hi.z; ++z)
    for (int32_t y = lo.y; y <= hi.y; ++y)
      for (int32_t x = lo.x; x <= hi.x; ++x) fn(ChunkCoord{x, y, z});
}

struct ChunkCoordHash {
  size_t operator()(const ChunkCoord& c) const noexcept {
    uint64_t h = static_cast<uint32_t>(c.x);
    h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(c.y);
    h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(c.z);
    h ^= h >> 29;
    return static_cast<size_t>(h * 0xBF58476D1CE4E5B9ull);
  }
};

}  // namespace vox::world
