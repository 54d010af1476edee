#include "server/world/zone.hpp"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <stdexcept>

namespace vox::world {
namespace {

void check_size(int size) {
  if (size < 1 || size > kMaxZoneChunks)
    throw std::invalid_argument("zone size must be 1 .. 65536 chunks");
}

// splitmix64's finaliser: every input bit moves every output bit.
uint64_t mix(uint64_t v) {
  v += 0x9e3779b97f4a7c15ull;
  v = (v ^ (v >> 30)) * 0xbf58476d1ce4e5b9ull;
  v = (v ^ (v >> 27)) * 0x94d049bb133111ebull;
  return v ^ (v >> 31);
}

}  // namespace

ZoneId zone_of(ChunkCoord c, int size) {
  check_size(size);
  return {floor_div(c.x, size), floor_div(c.z, size)};
}

std::vector<ZoneId> zones_of(const VoxelBox& box, int size) {
  const ZoneId lo = zone_of(chunk_of_voxel(box.lo[0], box.lo[1], box.lo[2]), size);
  const ZoneId hi = zone_of(chunk_of_voxel(box.hi[0], box.hi[1], box.hi[2]), size);
  std::vector<ZoneId> out;
  for (int32_t x = lo.x; x <= hi.x; ++x)
    for (int32_t z = lo.z; z <= hi.z; ++z) out.push_back({x, z});
  return out;
}

std::vector<VoxelBox> outside_zone(const VoxelBox& box, ZoneId zone, int size) {
  check_size(size);
  const int64_t side = int64_t{size} * kChunkSize;
  // The zone's voxel columns, clamped to what a box can hold.
  const auto clamp = [](int64_t v) {
    return static_cast<int32_t>(std::clamp<int64_t>(v, INT32_MIN, INT32_MAX));
  };
  const int32_t x0 = clamp(zone.x * side), x1 = clamp(zone.x * side + side - 1);
  const int32_t z0 = clamp(zone.z * side), z1 = clamp(zone.z * side + side - 1);
  std::vector<VoxelBox> out;
  const auto add = [&out](VoxelBox b) {
    if (b.lo[0] <= b.hi[0] && b.lo[2] <= b.hi[2]) out.push_back(b);
  };
  // Each bound is moved past the zone's only when the box reaches past it (no overflow).
  if (x0 > box.lo[0]) {
    VoxelBox b = box;  // whole z range, x below
    b.hi[0] = std::min(box.hi[0], x0 - 1);
    add(b);
  }
  if (x1 < box.hi[0]) {
    VoxelBox b = box;  // whole z range, x above
    b.lo[0] = std::max(box.lo[0], x1 + 1);
    add(b);
  }
  VoxelBox middle = box;  // x inside, z outside
  middle.lo[0] = std::max(box.lo[0], x0);
  middle.hi[0] = std::min(box.hi[0], x1);
  if (middle.lo[0] > middle.hi[0]) return out;
  if (z0 > box.lo[2]) {
    VoxelBox b = middle;
    b.hi[2] = std::min(box.hi[2], z0 - 1);
    add(b);
  }
  if (z1 < box.hi[2]) {
    VoxelBox b = middle;
    b.lo[2] = std::max(box.lo[2], z1 + 1);
    add(b);
  }
  return out;
}

uint64_t rendezvous_weight(ZoneId zone, std::string_view node) {
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a over the node id's bytes
  for (const char ch : node) h = (h ^ static_cast<uint8_t>(ch)) * 0x100000001b3ull;
  return mix(h ^ mix(zone.key()));
}

std::optional<size_t> first_ranked(ZoneId zone, std::span<const std::string> nodes) {
  std::optional<size_t> best;
  uint64_t best_weight = 0;
  for (size_t i = 0; i < nodes.size(); ++i) {
    const uint64_t w = rendezvous_weight(zone, nodes[i]);
    if (!best || w > best_weight || (w == best_weight && nodes[i] < nodes[*best])) {
      best = i;
      best_weight = w;
    }
  }
  return best;
}

}  // namespace vox::world
