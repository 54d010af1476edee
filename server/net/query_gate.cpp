#include "server/net/query_gate.hpp"

#include <algorithm>
#include <cmath>

namespace vox::net {

namespace {

bool finite(const wire::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

// The ray cut where it leaves the world's samples (it would read terrain no edit reaches
// and load it for nothing).
void clip_to_world(mesh::Ray& r, const world::EditLimits& limits) {
  const double o[3] = {r.origin.x, r.origin.y, r.origin.z};
  const double d[3] = {r.direction.x, r.direction.y, r.direction.z};
  double t = r.max_distance;
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = std::min(t, (limits.world_max[a] - o[a]) / d[a]);
    if (d[a] < 0) t = std::min(t, (limits.world_min[a] - o[a]) / d[a]);
  }
  r.max_distance = static_cast<float>(std::max(0.0, t));
}

}  // namespace

std::string QueryGate::check(const wire::Query& q, const world::EditLimits& limits,
                             const QueryLimits& config, pipeline::QueryTask& task) {
  const std::string longest = std::to_string(config.max_distance);
  switch (q.kind_case()) {
    case wire::Query::kRaycast: {
      const wire::Raycast& r = q.raycast();
      if (!finite(r.origin()) || !finite(r.direction()) || !std::isfinite(r.max_distance()))
        return "the raycast carries a value that is not finite";
      const double dx = r.direction().x(), dy = r.direction().y(), dz = r.direction().z();
      const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
      if (!(len > 1e-6) || !std::isfinite(len)) return "the raycast's direction has no length";
      if (!(r.max_distance() > 0) || r.max_distance() > config.max_distance)
        return "max_distance must be above 0 and at most " + longest;
      if (!world::inside_world(limits, r.origin().x(), r.origin().y(), r.origin().z()))
        return "the raycast's origin lies outside the world";
      task.ray = mesh::Ray{{r.origin().x(), r.origin().y(), r.origin().z()},
                           {static_cast<float>(dx / len), static_cast<float>(dy / len),
                            static_cast<float>(dz / len)},
                           r.max_distance()};
      clip_to_world(*task.ray, limits);
      return {};
    }
    case wire::Query::kGround: {
      const wire::GroundQuery& g = q.ground();
      if (!std::isfinite(g.x()) || !std::isfinite(g.z()) || !std::isfinite(g.from_y()) ||
          !std::isfinite(g.max_depth()))
        return "the ground query carries a value that is not finite";
      if (!(g.max_depth() > 0) || g.max_depth() > config.max_distance)
        return "max_depth must be above 0 and at most " + longest;
      if (!world::inside_world(limits, g.x(), g.from_y(), g.z()))
        return "the ground query's start lies outside the world";
      task.ray = mesh::Ray{{g.x(), g.from_y(), g.z()}, {0, -1, 0}, g.max_depth()};
      clip_to_world(*task.ray, limits);
      return {};
    }
    case wire::Query::kSamples: {
      const wire::VoxelBox& b = q.samples().box();
      const world::VoxelBox box{{b.min_x(), b.min_y(), b.min_z()},
                                {b.max_x(), b.max_y(), b.max_z()}};
      double samples = 1;
      for (int a = 0; a < 3; ++a) {
        if (box.lo[a] > box.hi[a]) return "the box's min must not lie above its max";
        if (box.lo[a] < limits.world_min[a] || box.hi[a] > limits.world_max[a])
          return "the box reaches outside the world";
        samples *= static_cast<double>(int64_t{box.hi[a]} - box.lo[a] + 1);
      }
      if (samples > config.max_samples)
        return "the box holds " + std::to_string(static_cast<uint64_t>(samples)) +
               " samples; at most " + std::to_string(config.max_samples);
      task.box = box;
      return {};
    }
    default:
      return "the Query carries no query";
  }
}

QueryGate::QueryGate(world::EditLimits world, QueryLimits limits, Clock::time_point now)
    : world_(world), limits_(limits), rate_(limits.rate, std::max(1.0, 2 * limits.rate), now) {}

std::optional<QueryGate::Refusal> QueryGate::admit(const wire::Query& query,
                                                   pipeline::QueryTask& task,
                                                   Clock::time_point now) {
  if (limits_.cluster)  // its chunks of other nodes' zones may be behind theirs
    return Refusal{wire::QueryResult::BAD_VALUE,
                   "queries are not available on a cluster world yet"};
  if (std::string why = check(query, world_, limits_, task); !why.empty())
    return Refusal{wire::QueryResult::BAD_VALUE, std::move(why)};
  if (in_flight_ >= limits_.max_in_flight)
    return Refusal{wire::QueryResult::TOO_MANY, "over " + std::to_string(limits_.max_in_flight) +
                                                    " queries still waiting for their answers"};
  if (const auto wait = rate_.take(1, now); wait.count() > 0)
    return Refusal{wire::QueryResult::RATE_LIMITED, "over the query rate",
                   static_cast<uint32_t>(std::min<int64_t>(wait.count(), 60000))};
  ++in_flight_;
  return std::nullopt;
}

}  // namespace vox::net
