#include "server/metrics/metrics_endpoint.hpp"

#include <prometheus/collectable.h>
#include <prometheus/exposer.h>
#include <prometheus/metric_family.h>

#include "server/pipeline/heap_stats.hpp"
#include "voxel.pb.h"

namespace vox::metrics {

namespace {

using prometheus::ClientMetric;
using prometheus::MetricFamily;
using prometheus::MetricType;

MetricFamily family(std::string name, std::string help, MetricType type) {
  return MetricFamily{std::move(name), std::move(help), type, {}};
}

void add(MetricFamily& f, double value, std::vector<ClientMetric::Label> labels = {}) {
  ClientMetric m;
  m.label = std::move(labels);
  if (f.type == MetricType::Counter) {
    m.counter.value = value;
  } else {
    m.gauge.value = value;
  }
  f.metric.push_back(std::move(m));
}

// A family of one unlabelled sample.
void single(std::vector<MetricFamily>& out, const char* name, const char* help, MetricType type,
            double value) {
  MetricFamily f = family(name, help, type);
  add(f, value);
  out.push_back(std::move(f));
}
void gauge(std::vector<MetricFamily>& out, const char* name, const char* help, double value) {
  single(out, name, help, MetricType::Gauge, value);
}
void counter(std::vector<MetricFamily>& out, const char* name, const char* help, double value) {
  single(out, name, help, MetricType::Counter, value);
}

MetricFamily histogram(std::string name, std::string help, const net::LatencyHistogram& h) {
  MetricFamily f = family(std::move(name), std::move(help), MetricType::Histogram);
  const auto snap = h.snapshot();
  ClientMetric m;
  for (size_t i = 0; i < net::LatencyHistogram::kBounds.size(); ++i) {
    m.histogram.bucket.push_back({snap.cumulative[i], net::LatencyHistogram::kBounds[i]});
  }
  m.histogram.bucket.push_back({snap.cumulative.back(), std::numeric_limits<double>::infinity()});
  m.histogram.sample_count = snap.cumulative.back();
  m.histogram.sample_sum = snap.sum;
  f.metric.push_back(std::move(m));
  return f;
}

double value_of(const std::atomic<uint64_t>& c) {
  return static_cast<double>(c.load(std::memory_order_relaxed));
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

class MetricsEndpoint::Collector : public prometheus::Collectable {
 public:
  Collector(const net::ServerCounters& counters, const pipeline::WorldPipeline& pipeline,
            Extra extra)
      : c_(counters), pipeline_(pipeline), extra_(std::move(extra)) {}

  std::vector<MetricFamily> Collect() const override {  // exposer threads
    std::vector<MetricFamily> out;
    if (extra_) {
      for (const ExtraFigure& f : extra_())
        single(out, f.name.c_str(), f.help.c_str(),
               f.counter ? MetricType::Counter : MetricType::Gauge, f.value);
    }
    connections(out);
    edits(out);
    world(out);
    traffic(out);
    out.push_back(
        histogram("voxeld_edit_publish_seconds",
                  "From an edit's submission to the pipeline to its result (its meshes published)",
                  c_.edit_to_publish));
    out.push_back(
        histogram("voxeld_edit_delta_written_seconds",
                  "From an edit's submission to the pipeline to a delta showing it written "
                  "to a player's socket (once per player who receives it)",
                  c_.edit_to_delta_written));
    out.push_back(histogram("voxeld_batch_duration_seconds", "World pipeline batch duration",
                            c_.batch_duration));
    out.push_back(histogram("voxeld_remesh_duration_seconds",
                            "Time to re-mesh and encode one batch's dirty chunks",
                            c_.remesh_duration));
    out.push_back(histogram(
        "voxeld_store_commit_seconds",
        "A transaction of the world store's edit log: the accepted edits of one batch, or "
        "of the batches queued while the one before was made durable",
        c_.store_commit));
    out.push_back(
        histogram("voxeld_store_commit_wait_seconds",
                  "How long the pipeline thread stood waiting for a batch's commit (0 when "
                  "it landed while other work went on)",
                  c_.store_commit_wait));
    counter(out, "voxeld_store_commits_total", "Transactions of the world store's edit log",
            double(c_.store_commits.load()));
    counter(out, "voxeld_store_committed_edits_total", "Edits appended to the world store",
            double(c_.store_committed_edits.load()));
    counter(out, "voxeld_store_failures_total",
            "Appends that failed (their edits refused STORAGE_UNAVAILABLE)",
            double(c_.store_failures.load()));
    out.push_back(histogram("voxeld_checkpoint_seconds",
                            "A checkpoint: compressing the changed chunks and writing them",
                            c_.checkpoint_duration));
    counter(out, "voxeld_checkpoint_bytes_total", "Chunk records written by checkpoints",
            double(c_.checkpoint_bytes.load()));
    return out;
  }

 private:
  void connections(std::vector<MetricFamily>& out) const {
    auto players = family("voxeld_players", "Connected players (past Hello)", MetricType::Gauge);
    add(players, value_of(c_.players));
    auto conns = family("voxeld_connections", "Open connections by state", MetricType::Gauge);
    add(conns, value_of(c_.handshaking), {{"state", "handshaking"}});
    add(conns, value_of(c_.players), {{"state", "player"}});
    auto refused = family("voxeld_connections_refused_total", "Connections or Hellos refused",
                          MetricType::Counter);
    const char* reasons[] = {"handshakes_full", "address_full", "server_full", "token", "banned"};
    static_assert(std::size(reasons) == static_cast<size_t>(net::RefusedBy::kCount));
    for (size_t i = 0; i < c_.refused.size(); ++i)
      add(refused, value_of(c_.refused[i]), {{"reason", reasons[i]}});
    auto disconnects = family("voxeld_disconnects_total",
                              "Connections the server closed, by reason", MetricType::Counter);
    add(disconnects, value_of(c_.dropped[static_cast<size_t>(net::DroppedBy::kSlowReader)]),
        {{"reason", "slow_reader"}});
    add(disconnects, value_of(c_.dropped[static_cast<size_t>(net::DroppedBy::kWriteTimeout)]),
        {{"reason", "write_timeout"}});
    for (auto code : {wire::Error::IDLE_TIMEOUT, wire::Error::HANDSHAKE_TIMEOUT,
                      wire::Error::FRAME_TIMEOUT, wire::Error::KICKED}) {
      add(disconnects, value_of(c_.errors_sent[code]),
          {{"reason", lower(wire::Error::Code_Name(code))}});
    }
    auto errors = family("voxeld_errors_sent_total", "Error messages sent to clients, by code",
                         MetricType::Counter);
    for (int code = 1; code < static_cast<int>(c_.errors_sent.size()); ++code) {
      if (!wire::Error::Code_IsValid(code)) continue;
      add(errors, value_of(c_.errors_sent[code]),
          {{"code", wire::Error::Code_Name(static_cast<wire::Error::Code>(code))}});
    }
    auto ws_closed = family("voxeld_websocket_closed_total",
                            "WebSocket connections closed for breaking the transport's rules",
                            MetricType::Counter);
    const char* ws_reasons[] = {"too_big", "text", "ping_flood", "frame_timeout", "protocol"};
    static_assert(std::size(ws_reasons) == static_cast<size_t>(net::WsClosedBy::kCount));
    for (size_t i = 0; i < c_.ws_closed.size(); ++i)
      add(ws_closed, value_of(c_.ws_closed[i]), {{"reason", ws_reasons[i]}});
    auto http_refused =
        family("voxeld_http_refused_total",
               "HTTP requests refused or connections closed, by reason", MetricType::Counter);
    const char* http_reasons[] = {"bad_request", "not_found", "bad_method", "header_too_big",
                                  "origin",      "busy",      "timeout"};
    static_assert(std::size(http_reasons) == static_cast<size_t>(net::HttpRefusedBy::kCount));
    for (size_t i = 0; i < c_.http_refused.size(); ++i)
      add(http_refused, value_of(c_.http_refused[i]), {{"reason", http_reasons[i]}});
    auto http = family("voxeld_http_requests_total", "HTTP requests answered", MetricType::Counter);
    add(http, value_of(c_.http_requests));
    auto upgrades = family("voxeld_websocket_upgrades_total", "WebSocket connections accepted",
                           MetricType::Counter);
    add(upgrades, value_of(c_.ws_upgrades));
    for (auto* f : {&players, &conns, &refused, &disconnects, &errors, &ws_closed, &http_refused,
                    &http, &upgrades})
      out.push_back(std::move(*f));
  }

  void edits(std::vector<MetricFamily>& out) const {
    auto edits = family("voxeld_edits_total", "Edit results, by status", MetricType::Counter);
    for (int s = 0; s < static_cast<int>(c_.edit_results.size()); ++s) {
      if (!wire::EditResult::Status_IsValid(s)) continue;
      add(edits, value_of(c_.edit_results[s]),
          {{"status",
            lower(wire::EditResult::Status_Name(static_cast<wire::EditResult::Status>(s)))}});
    }
    auto coalesced =
        family("voxeld_set_views_coalesced_total",
               "SetViews over the rate, coalesced into a newer one", MetricType::Counter);
    add(coalesced, value_of(c_.set_views_coalesced));
    auto paused =
        family("voxeld_reads_paused_total",
               "Times a connection was read slower for its message rate", MetricType::Counter);
    add(paused, value_of(c_.reads_paused));
    auto resynced = family("voxeld_chunks_resynced_total",
                           "Chunks clients asked for again in full (Resync)", MetricType::Counter);
    add(resynced, value_of(c_.chunks_resynced));
    for (auto* f : {&edits, &coalesced, &paused, &resynced}) out.push_back(std::move(*f));
  }

  void world(std::vector<MetricFamily>& out) const {
    const pipeline::PipelineStats s = pipeline_.stats();
    gauge(out, "voxeld_load_chunks_queued", "Chunks queued for loading (every view's)",
          double(s.queued_load_chunks));
    gauge(out, "voxeld_load_owners", "Views and loads with queued chunks", double(s.load_owners));
    gauge(out, "voxeld_chunks_generating",
          "Terrain chunks queued or ready in the background generator",
          double(s.chunks_generating));
    gauge(out, "voxeld_meshes_waiting", "Loaded chunks waiting for their neighbours' terrain",
          double(s.meshes_waiting));
    gauge(out, "voxeld_edits_queued", "Edits waiting for the next batch", double(s.queued_edits));
    gauge(out, "voxeld_chunks_loaded", "Chunks in memory", double(s.loaded_chunks));
    gauge(out, "voxeld_chunks_modified", "Resident chunks changed by edits",
          double(s.modified_chunks));
    gauge(out, "voxeld_chunks_unsaved",
          "Chunks changed since the last checkpoint (never evicted; their edits are in the log)",
          double(s.unsaved_chunks));
    gauge(out, "voxeld_chunks_stored", "Chunks the world store has a checkpoint of",
          double(s.stored_chunks));
    counter(out, "voxeld_checkpoints_total", "Checkpoints written", double(s.checkpoints));
    counter(out, "voxeld_checkpoint_failures_total", "Checkpoints the store refused",
            double(s.checkpoint_failures));
    gauge(out, "voxeld_checkpoint_sequence", "The newest checkpoint includes every edit to this",
          double(s.checkpoint_seq));
    gauge(out, "voxeld_meshes_loaded", "Published meshes in the store", double(s.mesh_count));
    gauge(out, "voxeld_lod_meshes_loaded",
          "Level-of-detail meshes (levels >= 1) some client's layout wants",
          double(s.lod_mesh_count));
    auto meshed = family(
        "voxeld_lod_meshes_made_total",
        "Level-of-detail meshes made, by level and cause: new to a layout, or re-meshed after "
        "an edit",
        MetricType::Counter);
    auto published = family("voxeld_lod_meshes_published_total",
                            "Of those, the ones that differed from the last (sent to clients)",
                            MetricType::Counter);
    for (size_t level = 1; level < s.lod_meshed.size(); ++level) {
      const std::string l = std::to_string(level);
      add(meshed, double(s.lod_remeshed[level]), {{"level", l}, {"cause", "edit"}});
      add(meshed,
          double(s.lod_meshed[level] - std::min(s.lod_meshed[level], s.lod_remeshed[level])),
          {{"level", l}, {"cause", "new"}});
      add(published, double(s.lod_published[level]), {{"level", l}});
    }
    out.push_back(std::move(meshed));
    out.push_back(std::move(published));
    auto accounted = family("voxeld_memory_accounted_bytes",
                            "Memory the budget counts, by part (unaccounted: the allocator's heap "
                            "beyond the other parts)",
                            MetricType::Gauge);
    add(accounted, double(s.chunk_bytes), {{"part", "chunks"}});
    add(accounted, double(s.mesh_bytes), {{"part", "meshes"}});
    add(accounted, double(s.lod_mesh_bytes), {{"part", "lod_meshes"}});
    add(accounted, double(s.session_bytes), {{"part", "sessions"}});
    add(accounted, double(s.unaccounted_bytes), {{"part", "unaccounted"}});
    out.push_back(std::move(accounted));
    gauge(out, "voxeld_memory_budget_bytes", "--max-memory", double(pipeline_.config().max_memory));
    gauge(out, "voxeld_loads_blocked", "1 while loads wait for memory", s.loads_blocked ? 1 : 0);
    gauge(out, "voxeld_resident_memory_bytes", "The process's resident set size",
          double(pipeline::process_resident_bytes()));
    if (const auto heap = pipeline::read_heap_stats()) {
      auto h =
          family("voxeld_heap_bytes", "The allocator's counters (jemalloc)", MetricType::Gauge);
      add(h, double(heap->allocated), {{"kind", "allocated"}});
      add(h, double(heap->active), {{"kind", "active"}});
      add(h, double(heap->resident), {{"kind", "resident"}});
      out.push_back(std::move(h));
    }
    counter(out, "voxeld_batches_total", "World pipeline batches", double(s.batches));
    counter(out, "voxeld_chunks_generated_total", "Chunks generated from the seed",
            double(s.chunks_generated));
    counter(out, "voxeld_chunks_evicted_total", "Chunks evicted", double(s.chunks_evicted));
    counter(out, "voxeld_meshes_published_total", "Mesh versions published",
            double(s.meshes_published));
    counter(out, "voxeld_memory_blocked_total", "Times loads started waiting for memory",
            double(s.memory_blocked));
  }

  void traffic(std::vector<MetricFamily>& out) const {
    counter(out, "voxeld_sent_bytes_total", "Bytes written to clients", value_of(c_.bytes_sent));
    counter(out, "voxeld_sent_messages_total", "Messages written to clients",
            value_of(c_.messages_sent));
    counter(out, "voxeld_meshes_sent_total", "ChunkMesh messages sent", value_of(c_.meshes_sent));
    counter(out, "voxeld_queries_total",
            "Raycast, ground and sample queries passed on to the world (not those refused at once)",
            value_of(c_.queries));
    counter(out, "voxeld_deltas_sent_total", "ChunkMesh messages sent as deltas",
            value_of(c_.deltas_sent));
    auto bytes = family("voxeld_mesh_payload_bytes_total",
                        "ChunkMesh payload bytes sent, by level and kind (full copy or delta)",
                        MetricType::Counter);
    auto messages = family("voxeld_mesh_messages_total",
                           "ChunkMesh messages sent, by level and kind (full copy or delta)",
                           MetricType::Counter);
    for (size_t level = 0; level < net::ServerCounters::kLevels; ++level) {
      for (size_t delta = 0; delta < 2; ++delta) {
        const std::vector<ClientMetric::Label> labels = {{"level", std::to_string(level)},
                                                         {"kind", delta ? "delta" : "full"}};
        add(bytes, value_of(c_.mesh_bytes[level][delta]), labels);
        add(messages, value_of(c_.mesh_messages[level][delta]), labels);
      }
    }
    out.push_back(std::move(bytes));
    out.push_back(std::move(messages));
  }

  const net::ServerCounters& c_;
  const pipeline::WorldPipeline& pipeline_;
  const Extra extra_;
};

MetricsEndpoint::MetricsEndpoint(const std::string& bind, uint16_t port,
                                 const net::ServerCounters& counters,
                                 const pipeline::WorldPipeline& pipeline, Extra extra)
    : collector_(std::make_shared<Collector>(counters, pipeline, std::move(extra))) {
  const std::string address =
      (bind.find(':') != std::string::npos ? "[" + bind + "]" : bind) + ":" + std::to_string(port);
  exposer_ = std::make_unique<prometheus::Exposer>(address, 2);
  exposer_->RegisterCollectable(collector_);
  const auto ports = exposer_->GetListeningPorts();
  port_ = ports.empty() ? port : static_cast<uint16_t>(ports.front());
}

MetricsEndpoint::~MetricsEndpoint() {
  if (exposer_) exposer_->RemoveCollectable(collector_);
}

}  // namespace vox::metrics
