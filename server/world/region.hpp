// Protected regions: boxes of samples that edits by players who do not own them leave as
// they are. A region protects against building (brush, smooth, paint, stamp), explosions,
// or both. An edit that reaches into one is clipped: the samples inside keep their values,
// everything outside changes as usual; an edit whose shape lies wholly inside one is
// refused. Admins are not held back by regions (the caller decides who is).
//
// Pure value types and functions: the pipeline thread owns the regions in force.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "server/world/edit.hpp"

namespace vox::world {

enum RegionFlag : uint8_t {
  kProtectBuild = 1,    // brush, smooth, paint, stamp
  kProtectExplode = 2,  // explosions
  kRegionFlagsKnown = kProtectBuild | kProtectExplode,
};

struct Region {
  uint64_t id = 0;   // assigned by the server, never reused
  std::string name;  // for people, 0..64 bytes
  VoxelBox box;      // the protected samples, inclusive world coordinates
  uint8_t flags = kRegionFlagsKnown;
  std::vector<std::string> owners;  // player ids that may edit inside it
  std::string created_by;           // the admin's player id (empty: an open server)
  int64_t created_unix_ms = 0;
};

struct RegionLimits {
  size_t max_regions = 4096;  // in the world
  size_t max_owners = 32;     // per region
  size_t max_name_bytes = 64;
  size_t max_owner_bytes = 64;  // a player id (as in a token)
};

// Why `r` cannot be added (its id is not looked at), or nullopt. Names and owners must be
// printable UTF-8 (they reach logs and tools); the box must lie inside the world.
std::optional<std::string> validate_region(const Region& r, const EditLimits& edit_limits,
                                           const RegionLimits& limits);

// The protection flag an edit must get past.
RegionFlag flag_for(const Edit& edit);
// The samples an edit aims at: touched_box() without a stamp's smooth boundary margin.
VoxelBox shape_box(const Edit& edit);

bool boxes_intersect(const VoxelBox& a, const VoxelBox& b);
bool box_contains(const VoxelBox& outer, const VoxelBox& inner);
VoxelBox box_intersection(const VoxelBox& a, const VoxelBox& b);  // call only if they intersect

struct Protection {
  // The parts of the edit's touched box it must leave as they are (each a region's box
  // clipped to the touched box), and the regions they belong to.
  std::vector<VoxelBox> keep;
  std::vector<uint64_t> regions;
  // The edit's shape lies wholly inside this region: it is refused.
  std::optional<uint64_t> forbidden_by;
};

// What `regions` hold back of `edit` made by player `author` (empty: no player id, owner
// of nothing). Linear in the regions.
Protection protection_for(std::span<const Region> regions, const Edit& edit,
                          std::string_view author);

}  // namespace vox::world
