// voxeld: flags, logging, signals; the server itself lives in the voxel_net library.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <boost/program_options.hpp>
#include <fstream>
#include <iostream>
#include <optional>
#include <thread>
#include <utility>

#include "server/auth/player_token.hpp"
#include "server/metrics/metrics_endpoint.hpp"
#include "server/net/server.hpp"
#include "server/store/world_store.hpp"

namespace po = boost::program_options;
namespace asio = boost::asio;

namespace {

// "1073741824", "512M", "2G", "64K" (binary units) -> bytes; nullopt when malformed.
std::optional<size_t> parse_bytes(const std::string& text) {
  size_t used = 0;
  unsigned long long value = 0;
  try {
    value = std::stoull(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  const std::string unit = text.substr(used);
  int shift = 0;
  if (unit == "K" || unit == "KiB")
    shift = 10;
  else if (unit == "M" || unit == "MiB")
    shift = 20;
  else if (unit == "G" || unit == "GiB")
    shift = 30;
  else if (!unit.empty())
    return std::nullopt;
  if (value > (SIZE_MAX >> shift)) return std::nullopt;
  return static_cast<size_t>(value) << shift;
}

// Written whole (renamed into place), so a script never reads half a number.
void write_port_file(const std::string& path, uint16_t port) {
  const std::string tmp = path + ".tmp";
  std::ofstream(tmp) << port << "\n";
  std::rename(tmp.c_str(), path.c_str());
}

// Half the machine's memory, at most 4 GiB: a dedicated server's share.
size_t default_max_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  const size_t half =
      pages > 0 && page > 0 ? static_cast<size_t>(pages) * page / 2 : size_t{1} << 30;
  return std::min(half, size_t{4} << 30);
}

// --auth-public-key / --open-role into `net`; false (with a one-line error) when unusable.
bool configure_identity(const std::string& key_file, const std::string& open_role,
                        vox::net::ServerConfig& net) {
  const auto role = vox::auth::parse_role(open_role);
  if (!role) {
    std::cerr << "voxeld: --open-role must be viewer, player or admin\n";
    return false;
  }
  net.open_role = *role;
  if (key_file.empty()) return true;
  vox::auth::init_crypto();
  std::ifstream in(key_file, std::ios::binary);
  if (!in) {
    std::cerr << "voxeld: --auth-public-key " << key_file << ": cannot be read\n";
    return false;
  }
  std::string text(256, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  net.auth_key = in || in.eof() ? vox::auth::key_from_text(text) : std::nullopt;
  if (!net.auth_key) {
    std::cerr << "voxeld: --auth-public-key " << key_file
              << ": not a public key file (one line of base64url, 32 bytes: voxel-cli keygen "
                 "writes NAME.pub; NAME.key is the private key and stays on the backend)\n";
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  vox::net::ServerConfig net;
  vox::pipeline::PipelineConfig world;
  std::string port_file, log_level, max_memory, metrics_port_file, world_dir, store_uri;
  std::string auth_key_file, open_role;
  bool in_memory = false;
  int metrics_port = -1;
  int io_threads = 1, stats_seconds = 10;
  long idle_ms = 60000, handshake_ms = 5000, write_ms = 10000, frame_ms = 10000,
       evict_after_s = 120;
  double checkpoint_s = 10;
  long lod_remesh_ms = 250;
  po::options_description opts("voxeld options");
  opts.add_options()("help,h", "show this help")(
      "port", po::value<uint16_t>(&net.port)->default_value(7777), "TCP port (0: pick a free one)")(
      "bind", po::value<std::string>(&net.bind)->default_value("127.0.0.1"),
      "address to listen on")("port-file", po::value<std::string>(&port_file),
                              "write the bound port to this file")(
      "metrics-port", po::value<int>(&metrics_port),
      "serve Prometheus metrics on /metrics at --bind:PORT (0: a free port)")(
      "metrics-port-file", po::value<std::string>(&metrics_port_file),
      "write the metrics port to this file")(
      "seed", po::value<uint64_t>(&world.seed),
      "world seed: recorded when the world is created (default 1); an existing world must "
      "have it")("world", po::value<std::string>(&world_dir)->default_value("world"),
                 "the world's directory (SQLite store; created on first start)")(
      "store", po::value<std::string>(&store_uri),
      "postgresql://... : keep the world in this PostgreSQL database instead of --world")(
      "checkpoint-interval", po::value<double>(&checkpoint_s)->default_value(10),
      "seconds between checkpoints of the changed chunks (sooner past 2,048 chunks or 20,000 "
      "edits); a restart replays the log since the last one")(
      "keep-log", po::bool_switch(&world.keep_log),
      "keep every edit in the log (an audit trail; voxel-cli world log) instead of deleting "
      "what a checkpoint includes")(
      "in-memory", po::bool_switch(&in_memory),
      "keep no world on disk: every edit is lost when voxeld stops (benchmarks)")(
      "threads", po::value<int>(&world.threads)->default_value(0),
      "world pipeline threads (0: all cores)")(
      "io-threads", po::value<int>(&io_threads)->default_value(1), "network threads")(
      "max-clients", po::value<size_t>(&net.max_clients)->default_value(256),
      "players beyond this are refused (SERVER_FULL)")(
      "max-handshaking", po::value<size_t>(&net.max_handshaking)->default_value(64),
      "connections before Hello (not players) at once")(
      "max-per-address", po::value<size_t>(&net.max_per_address)->default_value(16),
      "connections from one address (0: no cap)")(
      "max-handshaking-per-address",
      po::value<size_t>(&net.max_handshaking_per_address)->default_value(4),
      "of those, before Hello (0: no cap)")(
      "max-memory", po::value<std::string>(&max_memory),
      "memory budget for chunks, meshes and sessions, e.g. 2G (default: half the RAM, at most 4G)")(
      "load-budget", po::value<double>(&world.load_work_per_owner)->default_value(250),
      "terrain load work per second per player (4 per chunk generated, 1 per mesh; 0: unlimited)")(
      "load-burst", po::value<double>(&world.load_burst_per_owner)->default_value(4000),
      "load work a player may take at once (a first radius-4 view is 2,925)")(
      "load-budget-per-address",
      po::value<double>(&world.load_work_per_address)->default_value(1000),
      "load work per second for all players from one address together, burst 8x that; kept after "
      "they leave until refilled (0: unlimited)")(
      "edit-budget", po::value<double>(&net.edit_budget_rate)->default_value(300000),
      "samples per second a player's edits may touch, all its connections together (0: "
      "unlimited; a token's edit_rate overrides it)")(
      "edit-burst", po::value<double>(&net.edit_budget_burst)->default_value(600000),
      "samples a player's edits may touch at once")(
      "admin-edit-budget", po::value<double>(&net.admin_edit_budget_rate)->default_value(0),
      "the same for admins (0: unlimited)")(
      "admin-edit-burst", po::value<double>(&net.admin_edit_budget_burst)->default_value(0),
      "samples an admin's edits may touch at once")(
      "set-view-rate", po::value<double>(&net.set_view_rate)->default_value(2),
      "SetViews per second per player; more are coalesced (0: unlimited)")(
      "message-rate", po::value<double>(&net.message_rate)->default_value(200),
      "messages per second per connection before it is read slower (0: unlimited)")(
      "frame-timeout-ms", po::value<long>(&frame_ms)->default_value(10000),
      "a started frame must complete within this")(
      "evict-after", po::value<long>(&evict_after_s)->default_value(120),
      "seconds before an unused chunk (unmodified, or checkpointed) is evicted")(
      "max-view-radius", po::value<uint32_t>(&net.max_view_radius)->default_value(12),
      "largest view radius in chunks")(
      "max-lod-level", po::value<uint32_t>(&net.max_lod_level)->default_value(6),
      "coarsest level of detail a view may ask for (0: none; level 6 chunks are 2,048 voxels)")(
      "max-lod-distance", po::value<float>(&net.max_lod_distance)->default_value(2.0f),
      "largest SetView.lod_distance (1..4; larger: more coarse chunks per view)")(
      "lod-remesh-interval-ms", po::value<long>(&lod_remesh_ms)->default_value(250),
      "an edited coarse chunk is re-meshed at most this often (10..750; its update reaches "
      "players within about this plus a pass)")("idle-timeout-ms",
                                                po::value<long>(&idle_ms)->default_value(60000),
                                                "disconnect clients silent this long")(
      "handshake-timeout-ms", po::value<long>(&handshake_ms)->default_value(5000),
      "time allowed for Hello")("write-timeout-ms",
                                po::value<long>(&write_ms)->default_value(10000),
                                "disconnect clients that stop reading")(
      "stats-interval", po::value<int>(&stats_seconds)->default_value(10),
      "seconds between stats lines (0: none)")(
      "log-level", po::value<std::string>(&log_level)->default_value("info"),
      "trace, debug, info, warn, error")(
      "auth-public-key", po::value<std::string>(&auth_key_file),
      "players must present a token signed by this key (voxel-cli keygen writes NAME.pub)")(
      "open-role", po::value<std::string>(&open_role)->default_value("player"),
      "without --auth-public-key: every player's role (viewer, player or admin)");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, opts), vm);
    if (vm.count("help")) {
      std::cout << "usage: voxeld [options]\n" << opts;
      return 0;
    }
    po::notify(vm);
  } catch (const po::error& e) {
    std::cerr << "voxeld: " << e.what() << " (see --help)\n";
    return 2;
  }
  // The view radius bounds each session's memory (a ball of radius r holds ~4.2 r^3 chunks).
  if (io_threads < 1 || io_threads > 64 || world.threads < 0 || idle_ms <= 0 || handshake_ms <= 0 ||
      write_ms <= 0 || frame_ms <= 0 || evict_after_s < 1 || metrics_port > 65535 ||
      !(checkpoint_s >= 0.01 && checkpoint_s <= 86400) ||
      (vm.count("metrics-port") && metrics_port < 0) || net.max_view_radius > 32 ||
      net.max_lod_level > 6 || !(net.max_lod_distance >= 1.0f && net.max_lod_distance <= 4.0f) ||
      lod_remesh_ms < 10 || lod_remesh_ms > 750 || net.max_clients < 1 || net.max_handshaking < 1) {
    std::cerr << "voxeld: --io-threads must be 1..64, --threads >= 0, --max-view-radius <= 32, "
                 "--max-lod-level <= 6, --max-lod-distance 1..4, --lod-remesh-interval-ms 10..750, "
                 "--max-clients >= 1, "
                 "--max-handshaking >= 1, timeouts > 0, --checkpoint-interval 0.01..86400\n";
    return 2;
  }
  world.lod.remesh_interval = std::chrono::milliseconds(lod_remesh_ms);
  // The burst (8x) must hold one work unit, or no view of the address would ever load.
  if (!(world.load_work_per_address == 0 || world.load_work_per_address >= 0.125)) {
    std::cerr << "voxeld: --load-budget-per-address must be 0 (unlimited) or at least 0.125\n";
    return 2;
  }
  world.load_burst_per_address = 8 * world.load_work_per_address;
  // spdlog reads an unknown name as "off": a typo would silence the server.
  if (spdlog::level::from_str(log_level) == spdlog::level::off && log_level != "off") {
    std::cerr
        << "voxeld: --log-level must be trace, debug, info, warn, error, critical or off (got '"
        << log_level << "')\n";
    return 2;
  }
  // The largest edit (a box of side 2 * max radius, off the integer grid) must fit in the
  // budget's burst.
  const double largest_edit = vox::world::max_touched_samples(world.limits);
  if ((net.edit_budget_rate > 0 && net.edit_budget_burst < largest_edit) ||
      (net.admin_edit_budget_rate > 0 && net.admin_edit_budget_burst < largest_edit)) {
    std::cerr << "voxeld: --edit-burst and --admin-edit-burst must be at least "
              << static_cast<uint64_t>(largest_edit) << " samples (the largest edit)\n";
    return 2;
  }
  if (!configure_identity(auth_key_file, open_role, net)) return 2;
  if (max_memory.empty()) {
    world.max_memory = default_max_memory();
  } else if (auto bytes = parse_bytes(max_memory); bytes && *bytes >= (size_t{64} << 20)) {
    world.max_memory = *bytes;
  } else {
    std::cerr << "voxeld: --max-memory must be bytes with an optional K/M/G suffix, at least 64M\n";
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  net.idle_timeout = std::chrono::milliseconds(idle_ms);
  net.handshake_timeout = std::chrono::milliseconds(handshake_ms);
  net.write_timeout = std::chrono::milliseconds(write_ms);
  net.frame_timeout = std::chrono::milliseconds(frame_ms);
  world.evict_after = std::chrono::seconds(evict_after_s);
  world.checkpoint.interval = std::chrono::milliseconds(static_cast<long>(checkpoint_s * 1000));
  if (net.max_per_address == 0)
    spdlog::warn("--max-per-address 0: one address may fill the server");
  if (!net.auth_key) {
    spdlog::warn(
        "no --auth-public-key: the server is open; anyone may join under any name as "
        "'{}' (development mode)",
        vox::auth::to_string(net.open_role));
  }
#ifdef VOXEL_JEMALLOC
  constexpr const char* kAllocator = "jemalloc";
#else
  constexpr const char* kAllocator = "the system allocator";
#endif
  spdlog::info(
      "memory budget {} MiB (--max-memory, {}); per player: {:.0f} edit samples/s (burst {:.0f}), "
      "{} SetViews/s",
      world.max_memory >> 20, kAllocator, net.edit_budget_rate, net.edit_budget_burst,
      net.set_view_rate);

  // The durable world: opened (and checked) before anything listens.
  std::unique_ptr<vox::store::WorldStore> store, checkpoint_store;
  const std::optional<uint64_t> given_seed =
      vm.count("seed") ? std::optional<uint64_t>(world.seed) : std::nullopt;
  if (!store_uri.empty() && !vox::store::is_postgres_uri(store_uri)) {
    std::cerr << "voxeld: --store must be a postgresql:// URI (the default store is --world)\n";
    return 2;
  }
  if (in_memory) {
    world.seed = given_seed.value_or(1);
    spdlog::warn("--in-memory: no world on disk; every edit is lost when voxeld stops");
  } else {
    try {
      store = vox::store::open_world_store(store_uri.empty() ? world_dir : store_uri,
                                           {.seed = given_seed, .new_world_seed = 1});
      world.seed = store->info().seed;
      // Checkpoints are written on their own connection while edits are appended.
      checkpoint_store = vox::store::open_world_store(store_uri.empty() ? world_dir : store_uri,
                                                      {.seed = world.seed, .record_start = false});
    } catch (const std::exception& e) {
      std::cerr << "voxeld: " << e.what() << "\n";
      return 1;
    }
    world.store = store.get();
    world.checkpoint_store = checkpoint_store.get();
  }

  try {
    vox::net::ServerCounters counters;
    vox::pipeline::PipelineObserver observer{
        .batch = [&counters](double s, size_t, size_t) { counters.batch_duration.observe(s); },
        .remesh = [&counters](double s, size_t) { counters.remesh_duration.observe(s); },
        .commit =
            [&counters](double commit_s, size_t edits, bool ok) {
              if (!ok) return vox::net::ServerCounters::bump(counters.store_failures);
              counters.store_commit.observe(commit_s);
              vox::net::ServerCounters::bump(counters.store_commits);
              counters.store_committed_edits.fetch_add(edits, std::memory_order_relaxed);
            },
        .commit_wait = [&counters](double s) { counters.store_commit_wait.observe(s); },
        .checkpoint =
            [&counters](double s, size_t, size_t bytes, bool ok) {
              if (!ok) return;
              counters.checkpoint_duration.observe(s);
              counters.checkpoint_bytes.fetch_add(bytes, std::memory_order_relaxed);
            }};
    // Destroyed in reverse: the Server, then the io_context (its queued handlers and the
    // sessions they hold, which hold nothing of the Server), then the pipeline (sessions
    // drop their views in it) and the counters.
    vox::pipeline::WorldPipeline pipeline(world, observer);
    asio::io_context io;
    vox::net::Server server(io, net, pipeline, counters);
    server.start();
    std::unique_ptr<vox::metrics::MetricsEndpoint> metrics;
    if (metrics_port >= 0) {
      metrics = std::make_unique<vox::metrics::MetricsEndpoint>(
          net.bind, static_cast<uint16_t>(metrics_port), counters, pipeline);
      spdlog::info("metrics on http://{}:{}/metrics", net.bind, metrics->port());
      if (!metrics_port_file.empty()) write_port_file(metrics_port_file, metrics->port());
    }
    if (!port_file.empty()) write_port_file(port_file, server.port());
    if (stats_seconds > 0) server.start_stats_log(std::chrono::seconds(stats_seconds));
    asio::signal_set signals(io, SIGINT, SIGTERM);
    signals.async_wait([&](boost::system::error_code ec, int signal) {
      if (ec) return;
      spdlog::info("signal {}: shutting down", signal);
      server.stop();
      // Finish the batch in flight, then let the sessions flush their SHUTTING_DOWN.
      pipeline.stop();
      auto deadline = std::make_shared<asio::steady_timer>(io, std::chrono::seconds(2));
      deadline->async_wait([&io, deadline](boost::system::error_code) { io.stop(); });
    });
    std::vector<std::thread> threads;
    for (int i = 1; i < io_threads; ++i) threads.emplace_back([&io] { io.run(); });
    io.run();
    for (auto& t : threads) t.join();
    spdlog::info("voxeld stopped");
  } catch (const std::exception& e) {
    spdlog::error("voxeld: {}", e.what());
    return 1;
  }
  return 0;
}
