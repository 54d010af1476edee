#include "server/daemon/voxeld.hpp"

#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "server/cluster/cluster_config.hpp"
#include "server/cluster/cluster_node.hpp"
#include "server/daemon/json_log.hpp"
#include "server/daemon/reload.hpp"
#include "server/metrics/metrics_endpoint.hpp"
#include "server/net/server.hpp"
#include "server/store/ban_store.hpp"
#include "server/store/world_store.hpp"

namespace vox::daemon {
namespace {

namespace asio = boost::asio;

// Written whole (renamed into place), so a script never reads half a number.
void write_port_file(const std::string& path, uint16_t port) {
  const std::string tmp = path + ".tmp";
  std::ofstream(tmp) << port << "\n";
  std::rename(tmp.c_str(), path.c_str());
}

void log_start(const VoxeldConfig& c, const char* allocator) {
  if (c.net.max_per_address == 0)
    spdlog::warn("--max-per-address 0: one address may fill the server");
  if (!c.net.auth_key) {
    spdlog::warn(
        "no --auth-public-key: the server is open; anyone may join under any name as "
        "'{}' (development mode)",
        auth::to_string(c.net.open_role));
  }
  spdlog::info(
      "memory budget {} MiB (--max-memory, {}); per player: {:.0f} edit samples/s (burst {:.0f}), "
      "{} SetViews/s",
      c.world.max_memory >> 20, allocator, c.net.edit_budget_rate, c.net.edit_budget_burst,
      c.net.set_view_rate);
}

// The pipeline's durations into the server's counters.
pipeline::PipelineObserver observe_into(net::ServerCounters& counters) {
  return {.batch = [&counters](double s, size_t, size_t) { counters.batch_duration.observe(s); },
          .remesh = [&counters](double s, size_t) { counters.remesh_duration.observe(s); },
          .commit =
              [&counters](double commit_s, size_t edits, bool ok) {
                if (!ok) return net::ServerCounters::bump(counters.store_failures);
                counters.store_commit.observe(commit_s);
                net::ServerCounters::bump(counters.store_commits);
                counters.store_committed_edits.fetch_add(edits, std::memory_order_relaxed);
              },
          .commit_wait = [&counters](double s) { counters.store_commit_wait.observe(s); },
          .checkpoint =
              [&counters](double s, size_t, size_t bytes, bool ok) {
                if (!ok) return;
                counters.checkpoint_duration.observe(s);
                counters.checkpoint_bytes.fetch_add(bytes, std::memory_order_relaxed);
              }};
}

// The viewer's files as the build leaves them: web/ beside the bin/ voxeld runs from
// (build/web), or share/voxeld/web in an install; empty when neither exists.
std::filesystem::path default_http_root() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  for (const auto& candidate : {exe.parent_path().parent_path() / "web",
                                exe.parent_path().parent_path() / "share" / "voxeld" / "web"}) {
    if (std::filesystem::is_regular_file(candidate / "index.html", ec)) return candidate;
  }
  return {};
}

// A cluster node's figures on /metrics (none for a single node).
metrics::MetricsEndpoint::Extra cluster_figures(const cluster::ClusterNode* node) {
  if (!node) return {};
  return [node] {
    const cluster::ClusterNode::Figures f = node->figures();
    return std::vector<metrics::ExtraFigure>{
        {"voxeld_cluster_zones_held", "Zones this node holds", false, double(f.zones_held)},
        {"voxeld_cluster_zones_followed", "Zones followed for players' views", false,
         double(f.zones_followed)},
        {"voxeld_cluster_appends_fenced_total",
         "Appends refused because another node took the zone (the fence)", true,
         double(f.appends_fenced)},
        {"voxeld_cluster_edits_forwarded_total", "Edits sent to the node holding their zone", true,
         double(f.edits_forwarded)},
        {"voxeld_cluster_forwards_unheld_total", "Forwarded edits no node held the zone of", true,
         double(f.forwards_unheld)},
        {"voxeld_cluster_forwards_timed_out_total",
         "Forwarded edits whose holder did not answer within a lease", true,
         double(f.forwards_timed_out)},
        {"voxeld_cluster_edits_split_total",
         "Edits across zones not all held here, sent as one part per zone", true,
         double(f.edits_split)},
        {"voxeld_cluster_parts_completed_total",
         "Parts of edits across zones this node completed after their requests never came", true,
         double(f.parts_completed)},
        {"voxeld_cluster_checkpoints_written_total", "Zone checkpoints this node wrote", true,
         double(f.checkpoints_written)},
        {"voxeld_cluster_checkpoints_fenced_total",
         "Zone checkpoints refused because another node took the zone", true,
         double(f.checkpoints_fenced)},
        {"voxeld_cluster_checkpoints_installed_total",
         "Zone checkpoints installed instead of applying the records before them", true,
         double(f.checkpoints_installed)}};
  };
}

// SIGHUP: the flags and the --config file parsed again, and what may change applied:
// each change one log line, each change that needs a restart a warning; a configuration
// that does not parse changes nothing.
void reload(VoxeldConfig& current, net::Server& server) {
  VoxeldConfig next;
  std::ostringstream out, err;
  int parsed = 2;
  try {
    parsed = parse_voxeld_flags(current.args, next, out, err);
  } catch (const std::exception& e) {  // nothing known throws; a reload must not stop voxeld
    err << e.what() << "\n";
  }
  if (parsed != -1) {
    std::istringstream lines(err.str());
    for (std::string line; std::getline(lines, line);)
      spdlog::error("SIGHUP: {}; nothing changed", line);
    return;
  }
  ReloadPlan plan = plan_reload(current, next);
  for (const std::string& line : plan.changed) spdlog::info("SIGHUP: {}", line);
  for (const std::string& line : plan.kept) spdlog::warn("SIGHUP: {}", line);
  if (plan.changed.empty() && plan.kept.empty())
    spdlog::info("SIGHUP: the configuration is unchanged");
  current = std::move(plan.after);
  spdlog::set_level(spdlog::level::from_str(current.log_level));
  const net::ServerConfig& n = current.net;
  server.reload(
      {n.auth_key, n.edit_budget_rate, n.edit_budget_burst, n.admin_edit_budget_rate,
       n.admin_edit_budget_burst},
      {n.max_clients, n.max_handshaking, n.max_per_address, n.max_handshaking_per_address});
}

// Runs the opened world until a signal; throws what the server throws. `node`: a cluster
// node's links (null: a single node).
void serve(const VoxeldConfig& c, cluster::ClusterNode* node,
           std::shared_ptr<net::BanKeeper> bans) {
  net::ServerCounters counters;
  // Destroyed in reverse: the Server, then the io_context (its queued handlers and the
  // sessions they hold, which hold nothing of the Server but publication lists whose
  // deleters check that it is gone), then the pipeline (sessions drop their views in it)
  // and the counters.
  pipeline::WorldPipeline pipeline(c.world, observe_into(counters));
  asio::io_context io;
  net::Server server(io, c.net, pipeline, counters);
  if (bans) server.set_bans(bans);
  // Left by an exception: the node stops calling into the pipeline (forwarded edits,
  // parts it completes) and the sessions before they go. Otherwise stopped below.
  struct StopNode {
    cluster::ClusterNode* node;
    pipeline::WorldPipeline& pipeline;
    ~StopNode() {
      if (!node) return;
      pipeline.stop();    // first: its thread calls the node (admit, records)
      node->stop(false);  // both idempotent
    }
  } stop_node{node, pipeline};
  server.start();
  std::unique_ptr<metrics::MetricsEndpoint> metrics;
  if (c.metrics_port) {
    metrics = std::make_unique<metrics::MetricsEndpoint>(c.net.bind, *c.metrics_port, counters,
                                                         pipeline, cluster_figures(node));
    spdlog::info("metrics on http://{}:{}/metrics", c.net.bind, metrics->port());
    if (!c.metrics_port_file.empty()) write_port_file(c.metrics_port_file, metrics->port());
  }
  if (node) {
    node->set_submit([&pipeline](pipeline::EditTask task) { pipeline.submit(std::move(task)); });
    node->set_mesh_version([&pipeline](world::ChunkCoord chunk) -> uint64_t {
      const pipeline::MeshVersionPtr m = pipeline.meshes().get(chunk);
      return m ? m->version : 0;
    });
    node->start(c.net.bind + ":" + std::to_string(server.port()));
  }
  if (!c.port_file.empty()) write_port_file(c.port_file, server.port());
  if (server.http_port() != 0) {
    spdlog::info("open http://{}:{}/ in a browser", c.net.bind, server.http_port());
    if (!c.http_port_file.empty()) write_port_file(c.http_port_file, server.http_port());
  }
  if (c.stats_seconds > 0) server.start_stats_log(std::chrono::seconds(c.stats_seconds));
  // SIGHUP: the configuration and the bans are read again (reload.hpp; the README,
  // "Reloading the configuration"). On an io thread: the files are small.
  VoxeldConfig current = c;
  asio::signal_set hangups(io, SIGHUP);
  std::function<void()> arm_hangup = [&] {
    hangups.async_wait([&](boost::system::error_code ec, int) {
      if (ec) return;
      reload(current, server);
      if (bans) bans->reload();
      arm_hangup();
    });
  };
  arm_hangup();
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](boost::system::error_code ec, int signal) {
    if (ec) return;
    spdlog::info("signal {}: shutting down", signal);
    server.stop();
    hangups.cancel();
    // Finish the batch in flight, then let the sessions flush their SHUTTING_DOWN.
    pipeline.stop();
    auto deadline = std::make_shared<asio::steady_timer>(io, std::chrono::seconds(2));
    deadline->async_wait([&io, deadline](boost::system::error_code) { io.stop(); });
  });
  std::vector<std::thread> threads;
  for (int i = 1; i < c.io_threads; ++i) threads.emplace_back([&io] { io.run(); });
  io.run();
  for (auto& t : threads) t.join();
  metrics.reset();             // it reads the node's figures
  if (node) node->stop(true);  // the pipeline's appends landed: hand the zones off
}

// Why voxeld cannot start: on standard error as one plain line, or with --log-format json
// as a critical log line (a log shipper would drop the plain one, the most needed).
void start_failed(const VoxeldConfig& c, const std::string& why) {
  if (c.json_logs) {
    spdlog::critical("voxeld: {}", why);
  } else {
    std::cerr << "voxeld: " << why << "\n";
  }
}

}  // namespace

int run_voxeld(VoxeldConfig c, const char* allocator) {
  // SIGHUP (the bans read again) must not stop voxeld while it opens its world or after it
  // has stopped serving: ignored outside serve(), whose signal set takes it meanwhile.
  std::signal(SIGHUP, SIG_IGN);
  if (c.json_logs) use_json_logs();
  spdlog::set_level(spdlog::level::from_str(c.log_level));
  if (c.net.http && c.net.http->root.empty()) c.net.http->root = default_http_root();
  log_start(c, allocator);
  // The durable world: opened (and checked) before anything listens.
  std::unique_ptr<store::WorldStore> store, checkpoint_store, history_store;
  std::unique_ptr<cluster::ClusterNode> node;
  std::shared_ptr<net::BanKeeper> bans;  // none: in memory only
  if (!c.cluster_file.empty()) {
    try {
      c.world.seed = c.seed.value_or(1);
      cluster::ClusterConfig cc = cluster::read_cluster_config(c.cluster_file);
      // The cluster's bans: one table in its database, one world's rows per node set.
      bans = std::make_shared<net::BanKeeper>(store::open_ban_store(cc.database, cc.world));
      // Every node has the cluster's NATS password, no player has: the edit ids' key.
      if (cc.nats.password.empty())
        spdlog::warn("cluster: no nats_password: players could guess each other's edit ids");
      c.world.edit_id_key = pipeline::EditIds::key_from_secret(cc.world + '\n' + cc.nats.password);
      node = std::make_unique<cluster::ClusterNode>(std::move(cc), c.world.seed);
    } catch (const std::exception& e) {
      start_failed(c, e.what());
      return 1;
    }
    c.world.store = &node->store();
    c.world.checkpoint_store = &node->store();  // written on its own connection
    // The node outlives the server: GET /healthz asks it (a load balancer's check).
    if (c.net.http) c.net.http->unhealthy = [n = node.get()] { return n->unhealthy(); };
    c.world.zones = node.get();
  } else if (c.in_memory) {
    spdlog::warn("--in-memory: no world on disk; every edit is lost when voxeld stops");
  } else {
    const std::string where = c.store_uri.empty() ? c.world_dir : c.store_uri;
    try {
      store = store::open_world_store(where, {.seed = c.seed, .new_world_seed = 1});
      c.world.seed = store->info().seed;
      // Checkpoints are written on their own connection while edits are appended.
      checkpoint_store =
          store::open_world_store(where, {.seed = c.world.seed, .record_start = false});
      // Rollbacks read the history on theirs (pipeline/rollbacks.hpp).
      history_store = store::open_world_store(where, {.seed = c.world.seed, .record_start = false});
      bans = std::make_shared<net::BanKeeper>(store::open_ban_store(where));
    } catch (const std::exception& e) {
      start_failed(c, e.what());
      return 1;
    }
    c.world.store = store.get();
    c.world.checkpoint_store = checkpoint_store.get();
    c.world.history_store = history_store.get();
  }
  try {
    serve(c, node.get(), bans);
    std::signal(SIGHUP, SIG_IGN);  // Asio gave it back its default (ending the process)
    spdlog::info("voxeld stopped");
  } catch (const std::exception& e) {
    spdlog::error("voxeld: {}", e.what());
    return 1;
  }
  return 0;
}

}  // namespace vox::daemon
