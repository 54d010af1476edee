#include "server/world/edit.hpp"

#include <cmath>
#include <sstream>

namespace vox::world {
namespace {

bool finite(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

constexpr float kStampMargin = 2.0f;  // the stamp's boundary ramp

Refusal refuse(RefusalReason r, const std::string& what) {
  return {r, std::string(to_string(r)) + ": " + what};
}

std::optional<Refusal> check_radius(float radius, const EditLimits& limits) {
  if (!std::isfinite(radius)) return refuse(RefusalReason::kNotFinite, "radius");
  if (!(radius > 0.0f) || radius > limits.max_radius) {
    std::ostringstream s;
    s << "radius " << radius << " must be in (0, " << limits.max_radius << "]";
    return refuse(RefusalReason::kBadRadius, s.str());
  }
  return std::nullopt;
}

std::optional<Refusal> check_strength(float strength, const EditLimits& limits, const char* name) {
  if (!std::isfinite(strength)) return refuse(RefusalReason::kNotFinite, name);
  if (!(strength > 0.0f) || strength > limits.max_strength) {
    std::ostringstream s;
    s << name << " " << strength << " must be in (0, " << limits.max_strength << "]";
    return refuse(RefusalReason::kBadStrength, s.str());
  }
  return std::nullopt;
}

VoxelBox sphere_box(const Vec3& c, float r) {
  return {{static_cast<int32_t>(std::floor(c.x - r)), static_cast<int32_t>(std::floor(c.y - r)),
           static_cast<int32_t>(std::floor(c.z - r))},
          {static_cast<int32_t>(std::ceil(c.x + r)), static_cast<int32_t>(std::ceil(c.y + r)),
           static_cast<int32_t>(std::ceil(c.z + r))}};
}

// Checked in double so that huge coordinates cannot overflow int32 before the check.
std::optional<Refusal> check_bounds(const Vec3& lo, const Vec3& hi, const EditLimits& limits) {
  const double l[3] = {std::floor(lo.x), std::floor(lo.y), std::floor(lo.z)};
  const double h[3] = {std::ceil(hi.x), std::ceil(hi.y), std::ceil(hi.z)};
  for (int a = 0; a < 3; ++a) {
    if (l[a] < limits.world_min[a] || h[a] > limits.world_max[a]) {
      return refuse(RefusalReason::kOutOfBounds, "the edit reaches outside the world");
    }
  }
  return std::nullopt;
}

std::optional<Refusal> check_sphere(const Vec3& c, float r, const EditLimits& limits,
                                    float margin = 0) {
  if (!finite(c)) return refuse(RefusalReason::kNotFinite, "center");
  if (auto bad = check_radius(r, limits)) return bad;
  const float m = r + margin;
  return check_bounds({c.x - m, c.y - m, c.z - m}, {c.x + m, c.y + m, c.z + m}, limits);
}

}  // namespace

const char* to_string(RefusalReason r) {
  switch (r) {
    case RefusalReason::kNone:
      return "accepted";
    case RefusalReason::kNotFinite:
      return "not finite";
    case RefusalReason::kOutOfBounds:
      return "out of bounds";
    case RefusalReason::kBadRadius:
      return "bad radius";
    case RefusalReason::kBadStrength:
      return "bad strength";
    case RefusalReason::kBadMaterial:
      return "bad material";
    case RefusalReason::kShuttingDown:
      return "shutting down";
    case RefusalReason::kServerBusy:
      return "server busy";
    case RefusalReason::kOverBudget:
      return "over budget";
    case RefusalReason::kStorageUnavailable:
      return "storage unavailable";
    case RefusalReason::kForbidden:
      return "forbidden";
  }
  return "unknown";
}

std::optional<Refusal> validate(const Edit& edit, const EditLimits& limits) {
  struct Visitor {
    const EditLimits& limits;
    std::optional<Refusal> operator()(const Brush& b) const {
      if (auto bad = check_sphere(b.center, b.radius, limits)) return bad;
      if (auto bad = check_strength(b.strength, limits, "strength")) return bad;
      if (b.material && *b.material == kAir && !b.remove)
        return refuse(RefusalReason::kBadMaterial, "material 0 is air");
      return std::nullopt;
    }
    std::optional<Refusal> operator()(const Explosion& e) const {
      if (auto bad = check_sphere(e.center, e.radius, limits)) return bad;
      return check_strength(e.power, limits, "power");
    }
    std::optional<Refusal> operator()(const Smooth& s) const {
      if (auto bad = check_sphere(s.center, s.radius, limits, 1.0f))
        return bad;  // reads one sample further
      if (auto bad = check_strength(s.strength, limits, "strength")) return bad;
      if (s.strength > 1.0f)
        return refuse(RefusalReason::kBadStrength, "smooth strength must be in (0, 1]");
      return std::nullopt;
    }
    std::optional<Refusal> operator()(const Paint& p) const {
      if (auto bad = check_sphere(p.center, p.radius, limits)) return bad;
      if (p.material == kAir) return refuse(RefusalReason::kBadMaterial, "material 0 is air");
      return std::nullopt;
    }
    std::optional<Refusal> operator()(const Stamp& s) const {
      if (s.solid && s.material == kAir)
        return refuse(RefusalReason::kBadMaterial, "material 0 is air");
      if (s.shape == Stamp::Shape::kSphere)
        return check_sphere(s.center, s.radius, limits, kStampMargin);
      if (!finite(s.min) || !finite(s.max)) return refuse(RefusalReason::kNotFinite, "box corner");
      const float side[3] = {s.max.x - s.min.x, s.max.y - s.min.y, s.max.z - s.min.z};
      for (float d : side) {
        if (!(d > 0.0f) || d > 2 * limits.max_radius) {
          return refuse(RefusalReason::kBadRadius,
                        "box sides must be in (0, " + std::to_string(2 * limits.max_radius) + "]");
        }
      }
      const float m = kStampMargin;
      return check_bounds({s.min.x - m, s.min.y - m, s.min.z - m},
                          {s.max.x + m, s.max.y + m, s.max.z + m}, limits);
    }
  };
  return std::visit(Visitor{limits}, edit);
}

bool inside_world(const EditLimits& limits, double x, double y, double z) {
  const double p[3] = {x, y, z};
  for (int a = 0; a < 3; ++a)
    if (!(p[a] >= limits.world_min[a] && p[a] <= limits.world_max[a])) return false;
  return true;
}

VoxelBox chunk_box(ChunkCoord c) {
  const int32_t k = kChunkSize;
  return {{c.x * k, c.y * k, c.z * k}, {c.x * k + k - 1, c.y * k + k - 1, c.z * k + k - 1}};
}

VoxelBox touched_box(const Edit& edit) {
  struct Visitor {
    VoxelBox operator()(const Brush& b) const { return sphere_box(b.center, b.radius); }
    VoxelBox operator()(const Explosion& e) const { return sphere_box(e.center, e.radius); }
    VoxelBox operator()(const Smooth& s) const { return sphere_box(s.center, s.radius); }
    VoxelBox operator()(const Paint& p) const { return sphere_box(p.center, p.radius); }
    VoxelBox operator()(const Stamp& s) const {
      if (s.shape == Stamp::Shape::kSphere) return sphere_box(s.center, s.radius + kStampMargin);
      const float m = kStampMargin;
      return {{static_cast<int32_t>(std::floor(s.min.x - m)),
               static_cast<int32_t>(std::floor(s.min.y - m)),
               static_cast<int32_t>(std::floor(s.min.z - m))},
              {static_cast<int32_t>(std::ceil(s.max.x + m)),
               static_cast<int32_t>(std::ceil(s.max.y + m)),
               static_cast<int32_t>(std::ceil(s.max.z + m))}};
    }
  };
  return std::visit(Visitor{}, edit);
}

double max_touched_samples(const EditLimits& limits) {
  return std::pow(2.0 * (static_cast<double>(limits.max_radius) + kStampMargin) + 2, 3);
}

}  // namespace vox::world
