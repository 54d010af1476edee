// The session's queries (docs/PROTOCOL.md 4.13): raycast, ground and samples, for every
// role. Checked here, answered by the pipeline in order with the edits, at most
// max_queries_in_flight of a client waiting and query_rate of them a second. Strand only,
// but where a comment says otherwise.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "server/net/client_session.hpp"
#include "server/net/wire_convert.hpp"

namespace vox::net {

namespace {

// SERVER_BUSY and STORAGE_UNAVAILABLE: memory frees as eviction runs; a query over its
// loads goes on at once.
constexpr uint32_t kBusyRetryMs = 1000;
constexpr uint32_t kMoreLoadsRetryMs = 50;

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

wire::Vec3 to_wire(const mesh::Vec3f& v) {
  wire::Vec3 w;
  w.set_x(v.x), w.set_y(v.y), w.set_z(v.z);
  return w;
}

// The query as the pipeline takes it, or why it is refused (BAD_VALUE).
std::string check_query(const wire::Query& q, const world::EditLimits& limits,
                        const ServerConfig& config, pipeline::QueryTask& task) {
  const std::string longest = std::to_string(config.max_query_distance);
  switch (q.kind_case()) {
    case wire::Query::kRaycast: {
      const wire::Raycast& r = q.raycast();
      if (!finite(r.origin()) || !finite(r.direction()) || !std::isfinite(r.max_distance()))
        return "the raycast carries a value that is not finite";
      const double dx = r.direction().x(), dy = r.direction().y(), dz = r.direction().z();
      const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
      if (!(len > 1e-6) || !std::isfinite(len)) return "the raycast's direction has no length";
      if (!(r.max_distance() > 0) || r.max_distance() > config.max_query_distance)
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
      if (!(g.max_depth() > 0) || g.max_depth() > config.max_query_distance)
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
      if (samples > config.max_query_samples)
        return "the box holds " + std::to_string(static_cast<uint64_t>(samples)) +
               " samples; at most " + std::to_string(config.max_query_samples);
      task.box = box;
      return {};
    }
    default:
      return "the Query carries no query";
  }
}

wire::QueryResult::Status query_status(world::RefusalReason r) {
  switch (r) {
    case world::RefusalReason::kNone:
      return wire::QueryResult::OK;
    case world::RefusalReason::kStorageUnavailable:
      return wire::QueryResult::STORAGE_UNAVAILABLE;
    case world::RefusalReason::kShuttingDown:
      return wire::QueryResult::SHUTTING_DOWN;
    default:  // kOverBudget (more loads than one query makes), kServerBusy
      return wire::QueryResult::SERVER_BUSY;
  }
}

}  // namespace

void ClientSession::handle_query(const wire::Query& query) {
  wire::Envelope reply;
  auto* result = reply.mutable_query_result();
  result->set_request_id(query.request_id());
  auto refuse = [&](wire::QueryResult::Status status, const std::string& reason,
                    uint32_t retry_after_ms = 0) {
    result->set_status(status);
    result->set_reason(reason);
    result->set_retry_after_ms(retry_after_ms);
    if (auto suppressed = services_.logs->allow("query-refused", 5)) {
      spdlog::info("session {}: a query of '{}' refused: {}{}", id_, log_name_,
                   escape_for_log(reason, 200),
                   *suppressed ? fmt::format(" [{} more refused]", *suppressed) : std::string());
    }
    queue_control(reply);
  };
  if (pipeline_.config().zones)  // its chunks of other nodes' zones may be behind theirs
    return refuse(wire::QueryResult::BAD_VALUE, "queries are not available on a cluster world yet");
  pipeline::QueryTask task;
  if (std::string why = check_query(query, pipeline_.config().limits, config_, task); !why.empty())
    return refuse(wire::QueryResult::BAD_VALUE, why);
  if (queries_in_flight_ >= config_.max_queries_in_flight)
    return refuse(wire::QueryResult::TOO_MANY, "over " +
                                                   std::to_string(config_.max_queries_in_flight) +
                                                   " queries still waiting for their answers");
  const auto wait = query_budget_.take(1, std::chrono::steady_clock::now());
  if (wait.count() > 0)
    return refuse(wire::QueryResult::RATE_LIMITED, "over the query rate",
                  static_cast<uint32_t>(std::min<int64_t>(wait.count(), 60000)));
  if (task.ray) {
    result->set_hit(false);
  } else {
    const world::VoxelBox& b = task.box;
    auto* box = result->mutable_box();
    box->set_min_x(b.lo[0]), box->set_min_y(b.lo[1]), box->set_min_z(b.lo[2]);
    box->set_max_x(b.hi[0]), box->set_max_y(b.hi[1]), box->set_max_z(b.hi[2]);
  }
  ++queries_in_flight_;
  counters_.queries.fetch_add(1, std::memory_order_relaxed);
  task.done = [self = shared_from_this(), reply](const pipeline::QueryAnswer& a) mutable {
    // Pipeline thread: build the answer here, queue it on the strand.
    auto* r = reply.mutable_query_result();
    r->set_status(query_status(a.reason));
    if (a.reason != world::RefusalReason::kNone) {
      r->clear_box();
      r->set_reason(a.message);
      if (a.reason != world::RefusalReason::kShuttingDown)
        r->set_retry_after_ms(a.retry_after_ms > 0                            ? a.retry_after_ms
                              : a.reason == world::RefusalReason::kOverBudget ? kMoreLoadsRetryMs
                                                                              : kBusyRetryMs);
    } else if (r->has_box()) {
      r->set_densities(a.densities);
      r->set_materials(a.materials);
    } else if (a.hit.hit) {
      r->set_hit(true);
      *r->mutable_point() = to_wire(a.hit.point);
      *r->mutable_normal() = to_wire(a.hit.normal);
      r->set_material(a.hit.material);
      r->set_distance(a.hit.distance);
    }
    asio::post(self->strand_, [self, reply = std::move(reply)] {
      --self->queries_in_flight_;
      self->queue_control(reply);
    });
  };
  pipeline_.query(std::move(task));
}

}  // namespace vox::net
