// Prometheus text format on /metrics (prometheus-cpp's pull exposer), built at scrape time
// from the counters the server already keeps and the pipeline's stats: nothing on the hot
// paths changes for it. The exposer runs its own threads; a scrape only reads atomics and
// takes the pipeline's stats locks (leaf locks) briefly.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "server/net/server_counters.hpp"
#include "server/pipeline/world_pipeline.hpp"

namespace prometheus {
class Exposer;
}

namespace vox::metrics {

class MetricsEndpoint {
 public:
  // Listens on bind:port (0: a free port); throws std::exception when it cannot.
  MetricsEndpoint(const std::string& bind, uint16_t port, const net::ServerCounters& counters,
                  const pipeline::WorldPipeline& pipeline);
  ~MetricsEndpoint();
  uint16_t port() const { return port_; }

 private:
  class Collector;
  std::shared_ptr<Collector> collector_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  uint16_t port_ = 0;
};

}  // namespace vox::metrics
