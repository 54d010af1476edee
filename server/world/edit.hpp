// Edits: plain value types, validated before they are applied. An invalid edit is
// refused with a reason and changes nothing.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>

#include "server/world/chunk_coord.hpp"
#include "server/world/sample.hpp"

namespace vox::world {

struct Vec3 {
  float x = 0, y = 0, z = 0;
};

// Adds (or with `remove`, takes away) material in a sphere: strength * (1 - (d/r)^2)^2,
// densities clamped to [-1, 1]. Where it adds and a sample turns solid, the sample gets
// `material` (or keeps its own, or becomes dirt when it was air and none is given).
struct Brush {
  Vec3 center;
  float radius = 1;
  float strength = 0.5f;
  bool remove = false;
  std::optional<Material> material;
};
// Removes power * (1 - d/r)^2 of density in a sphere.
struct Explosion {
  Vec3 center;
  float radius = 1;
  float power = 1;
};
// Moves densities toward the 3x3x3 average by strength * (1 - (d/r)^2)^2.
struct Smooth {
  Vec3 center;
  float radius = 1;
  float strength = 0.5f;
};
// Sets the material of solid samples in a sphere; the shape does not change.
struct Paint {
  Vec3 center;
  float radius = 1;
  Material material = 1;
};
// Makes a box (min..max corners) or a sphere solid with `material`, or air: a union or a
// subtraction of the shape with the terrain, with a smooth 2-voxel boundary.
struct Stamp {
  enum class Shape : uint8_t { kBox, kSphere };
  Shape shape = Shape::kBox;
  Vec3 min, max;     // box
  Vec3 center;       // sphere
  float radius = 1;  // sphere
  bool solid = true;
  Material material = 3;
};

using Edit = std::variant<Brush, Explosion, Smooth, Paint, Stamp>;

enum class RefusalReason : uint8_t {
  kNone = 0,
  kNotFinite,           // a coordinate, radius or strength is NaN or infinite
  kOutOfBounds,         // the edit reaches outside the world's bounds
  kBadRadius,           // radius <= 0 or over the limit (or a box side over it)
  kBadStrength,         // strength / power <= 0 or over the limit
  kBadMaterial,         // material 0 (air) where a solid material is needed
  kShuttingDown,        // the pipeline stopped before applying it
  kServerBusy,          // it needs chunks loaded while the memory budget is full
  kOverBudget,          // its sender's edits made the server generate too much terrain at once
  kStorageUnavailable,  // the world store could not make it durable: it was not applied
  kForbidden,           // its shape lies wholly inside a protected region (region.hpp)
};
const char* to_string(RefusalReason r);

struct EditLimits {
  float max_radius = 32;   // voxels; box stamps: max side 2 * max_radius
  float max_strength = 4;  // brush/smooth strength and explosion power
  // World bounds in voxels, inclusive; every sample an edit can touch must lie inside.
  std::array<int32_t, 3> world_min{-1 << 20, -1 << 12, -1 << 20};
  std::array<int32_t, 3> world_max{(1 << 20) - 1, (1 << 12) - 1, (1 << 20) - 1};
};

struct Refusal {
  RefusalReason reason = RefusalReason::kNone;
  std::string message;
};

// Samples an edit may change, inclusive voxel bounds.
struct VoxelBox {
  std::array<int32_t, 3> lo{}, hi{};
};

std::optional<Refusal> validate(const Edit& edit, const EditLimits& limits);
// Call only on a valid edit.
VoxelBox touched_box(const Edit& edit);
// Whether a position (a view's, a ray's origin) lies in the world: world_min ≤ p ≤ world_max
// on each axis.
bool inside_world(const EditLimits& limits, double x, double y, double z);
// Every sample of chunk `c`.
VoxelBox chunk_box(ChunkCoord c);
// The most samples touched_box() holds for an edit valid under `limits`: a stamp spans
// 2 * (max_radius + its 2-voxel margin) per axis, and floor(lo)..ceil(hi) of a span off
// the integer grid holds 2 samples more, so (2 * max_radius + 6)^3.
double max_touched_samples(const EditLimits& limits);

}  // namespace vox::world
