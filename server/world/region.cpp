#include "server/world/region.hpp"

#include <algorithm>
#include <cmath>

namespace vox::world {
namespace {

bool printable(std::string_view s) {
  for (const char ch : s) {
    const auto b = static_cast<unsigned char>(ch);
    if (b < 0x20 || b == 0x7f) return false;
  }
  return true;
}

}  // namespace

std::optional<std::string> validate_region(const Region& r, const EditLimits& edit_limits,
                                           const RegionLimits& limits) {
  if (r.name.size() > limits.max_name_bytes || !printable(r.name))
    return "a region name is 0.." + std::to_string(limits.max_name_bytes) +
           " bytes without control characters";
  if ((r.flags & kRegionFlagsKnown) == 0 || (r.flags & ~kRegionFlagsKnown) != 0)
    return "a region protects against building, explosions or both";
  for (int a = 0; a < 3; ++a) {
    if (r.box.lo[a] > r.box.hi[a]) return "a region's min corner must not exceed its max corner";
    if (r.box.lo[a] < edit_limits.world_min[a] || r.box.hi[a] > edit_limits.world_max[a])
      return "the region is outside the world";
  }
  if (r.owners.size() > limits.max_owners)
    return "a region has at most " + std::to_string(limits.max_owners) + " owners";
  for (const std::string& o : r.owners) {
    if (o.empty() || o.size() > limits.max_owner_bytes || !printable(o))
      return "an owner is a player id of 1.." + std::to_string(limits.max_owner_bytes) +
             " bytes without control characters";
  }
  return std::nullopt;
}

RegionFlag flag_for(const Edit& edit) {
  return std::holds_alternative<Explosion>(edit) ? kProtectExplode : kProtectBuild;
}

VoxelBox shape_box(const Edit& edit) {
  const auto* stamp = std::get_if<Stamp>(&edit);
  if (!stamp) return touched_box(edit);
  float lo[3], hi[3];
  if (stamp->shape == Stamp::Shape::kSphere) {
    const float c[3] = {stamp->center.x, stamp->center.y, stamp->center.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = c[a] - stamp->radius;
      hi[a] = c[a] + stamp->radius;
    }
  } else {
    lo[0] = stamp->min.x, lo[1] = stamp->min.y, lo[2] = stamp->min.z;
    hi[0] = stamp->max.x, hi[1] = stamp->max.y, hi[2] = stamp->max.z;
  }
  VoxelBox box;
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = static_cast<int32_t>(std::floor(lo[a]));
    box.hi[a] = static_cast<int32_t>(std::ceil(hi[a]));
  }
  return box;
}

bool boxes_intersect(const VoxelBox& a, const VoxelBox& b) {
  for (int i = 0; i < 3; ++i)
    if (a.hi[i] < b.lo[i] || b.hi[i] < a.lo[i]) return false;
  return true;
}

bool box_contains(const VoxelBox& outer, const VoxelBox& inner) {
  for (int i = 0; i < 3; ++i)
    if (inner.lo[i] < outer.lo[i] || inner.hi[i] > outer.hi[i]) return false;
  return true;
}

VoxelBox box_intersection(const VoxelBox& a, const VoxelBox& b) {
  VoxelBox r;
  for (int i = 0; i < 3; ++i) {
    r.lo[i] = std::max(a.lo[i], b.lo[i]);
    r.hi[i] = std::min(a.hi[i], b.hi[i]);
  }
  return r;
}

Protection protection_for(std::span<const Region> regions, const Edit& edit,
                          std::string_view author) {
  Protection p;
  if (regions.empty()) return p;
  const RegionFlag flag = flag_for(edit);
  const VoxelBox touched = touched_box(edit);
  const VoxelBox shape = shape_box(edit);
  for (const Region& r : regions) {
    if ((r.flags & flag) == 0 || !boxes_intersect(r.box, touched)) continue;
    if (!author.empty() && std::find(r.owners.begin(), r.owners.end(), author) != r.owners.end())
      continue;
    if (box_contains(r.box, shape)) {
      p.forbidden_by = r.id;
      p.keep.clear();
      p.regions.clear();
      return p;
    }
    p.keep.push_back(box_intersection(r.box, touched));
    p.regions.push_back(r.id);
  }
  return p;
}

}  // namespace vox::world
