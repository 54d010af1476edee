// Whether a client's query (docs/PROTOCOL.md 4.13) goes to the pipeline or is answered at
// once: its values (finite, within the world and the limits; a ray is cut at the world's
// edge), a cap on its queries waiting, and its query rate. Pure but for the clock it is
// given; the session's strand only.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/token_bucket.hpp"
#include "server/world/edit.hpp"
#include "voxel.pb.h"

namespace vox::net {

struct QueryLimits {
  float max_distance = 512;             // a ray's length
  uint32_t max_samples = 32 * 32 * 32;  // a SampleQuery's box
  size_t max_in_flight = 8;             // queries waiting at once
  double rate = 20;                     // a second, a burst of twice as many (at least 1)
  bool cluster = false;                 // a cluster world: refused
};

class QueryGate {
 public:
  using Clock = std::chrono::steady_clock;

  QueryGate(world::EditLimits world, QueryLimits limits, Clock::time_point now = Clock::now());

  struct Refusal {
    wire::QueryResult::Status status;
    std::string reason;
    uint32_t retry_after_ms = 0;
  };
  // Admits the query into `task` (then it counts in flight until answered()) or says why
  // not.
  std::optional<Refusal> admit(const wire::Query& query, pipeline::QueryTask& task,
                               Clock::time_point now);
  void answered() { --in_flight_; }
  size_t in_flight() const { return in_flight_; }

  // The query as the pipeline takes it, or why it is refused (BAD_VALUE): empty when valid.
  static std::string check(const wire::Query& query, const world::EditLimits& world,
                           const QueryLimits& limits, pipeline::QueryTask& task);

 private:
  const world::EditLimits world_;
  const QueryLimits limits_;
  pipeline::TokenBucket rate_;
  size_t in_flight_ = 0;
};

}  // namespace vox::net
