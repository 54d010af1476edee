// Prometheus text format on /metrics (prometheus-cpp's pull exposer), built at scrape time
// from the counters the server already keeps and the pipeline's stats: nothing on the hot
// paths changes for it. The exposer runs its own threads; a scrape only reads atomics and
// takes the pipeline's stats locks (leaf locks) briefly.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "server/net/server_counters.hpp"
#include "server/pipeline/world_pipeline.hpp"

namespace prometheus {
class Exposer;
}

namespace vox::metrics {

// A figure of a part the endpoint does not know (a cluster node's), read at each scrape.
struct ExtraFigure {
  std::string name, help;
  bool counter = false;  // else a gauge
  double value = 0;
};

class MetricsEndpoint {
 public:
  using Extra = std::function<std::vector<ExtraFigure>()>;  // called on the exposer's threads
  // Listens on bind:port (0: a free port); throws std::exception when it cannot.
  MetricsEndpoint(const std::string& bind, uint16_t port, const net::ServerCounters& counters,
                  const pipeline::WorldPipeline& pipeline, Extra extra = {});
  ~MetricsEndpoint();
  uint16_t port() const { return port_; }

 private:
  class Collector;
  std::shared_ptr<Collector> collector_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  uint16_t port_ = 0;
};

}  // namespace vox::metrics
