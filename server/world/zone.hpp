// Zones: the units a world is split into over several voxeld nodes (the scale-out issue
// calls them regions; here "region" already names protected regions). A zone is a
// vertical column of size × size chunks, all heights; each has one owner node at a time,
// which sequences, applies and logs its edits.
//
// Placement is rendezvous (highest random weight) hashing: each (zone, node) pair gets a
// weight from a fixed 64-bit hash, the same on every node and every build (not
// std::hash), and a zone goes to the live node of highest weight. A node that leaves moves
// only its own zones; one that joins takes only those it now ranks first for.
//
// Pure values and functions: any thread.
#pragma once

#include <compare>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"

namespace vox::world {

inline constexpr int kDefaultZoneChunks = 16;  // 512 × 512 voxels
inline constexpr int kMaxZoneChunks = 1 << 16;

struct ZoneId {
  int32_t x = 0, z = 0;  // in zones: chunk x / size, rounded down
  friend auto operator<=>(const ZoneId&, const ZoneId&) = default;
  // One 64-bit key (database rows, subjects): x in the high half, z in the low, each as
  // its two's complement bits.
  uint64_t key() const {
    return (uint64_t{static_cast<uint32_t>(x)} << 32) | uint64_t{static_cast<uint32_t>(z)};
  }
  static ZoneId from_key(uint64_t k) {
    return {static_cast<int32_t>(static_cast<uint32_t>(k >> 32)),
            static_cast<int32_t>(static_cast<uint32_t>(k))};
  }
};

// The zone of chunk c, for zones of `size` chunks a side (1 .. kMaxZoneChunks).
ZoneId zone_of(ChunkCoord c, int size);
// The zones whose chunks hold a voxel of `box` (inclusive), in (x, z) order.
std::vector<ZoneId> zones_of(const VoxelBox& box, int size);

// The parts of `box` (inclusive) outside `zone`'s columns: none when the box lies in it,
// else up to four boxes. An edit logged in one zone keeps these samples as they are, so it
// changes only its own zone's (docs/CLUSTER.md, "Edits across a border").
std::vector<VoxelBox> outside_zone(const VoxelBox& box, ZoneId zone, int size);

// The weight of `node` for `zone`: a 64-bit hash of both.
uint64_t rendezvous_weight(ZoneId zone, std::string_view node);
// Which of `nodes` ranks first for `zone` (ties: the smaller id); nullopt when none.
std::optional<size_t> first_ranked(ZoneId zone, std::span<const std::string> nodes);

}  // namespace vox::world
