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

wire::Vec3 to_wire(const mesh::Vec3f& v) {
  wire::Vec3 w;
  w.set_x(v.x), w.set_y(v.y), w.set_z(v.z);
  return w;
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
  pipeline::QueryTask task;
  if (auto refused = queries_.admit(query, task, std::chrono::steady_clock::now()))
    return refuse(refused->status, refused->reason, refused->retry_after_ms);
  if (task.ray) {
    result->set_hit(false);
  } else {
    const world::VoxelBox& b = task.box;
    auto* box = result->mutable_box();
    box->set_min_x(b.lo[0]), box->set_min_y(b.lo[1]), box->set_min_z(b.lo[2]);
    box->set_max_x(b.hi[0]), box->set_max_y(b.hi[1]), box->set_max_z(b.hi[2]);
  }
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
      self->queries_.answered();
      self->queue_control(reply);
    });
  };
  pipeline_.query(std::move(task));
}

}  // namespace vox::net
