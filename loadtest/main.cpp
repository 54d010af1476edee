// voxel-loadtest: thin entry point; the simulation lives in the voxel_loadtest library.
#include <unistd.h>

#include <algorithm>
#include <boost/program_options.hpp>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

#include "loadtest/load_test.hpp"
#include "loadtest/player_tokens.hpp"
#include "loadtest/report_svg.hpp"
#include "loadtest/sweep.hpp"
#include "loadtest/timeline.hpp"
#include "options/option_values.hpp"
#include "server/world/terrain_generator.hpp"

namespace {
// The simulated players walk on the server's own terrain: the one place the load tester
// knows the world beyond the protocol (the library does not; docs/ARCHITECTURE.md).
vox::loadtest::GroundHeight ground_for_seed(uint64_t seed) {
  auto terrain = std::make_shared<const vox::world::TerrainGenerator>(seed);
  return [terrain](int x, int z) { return static_cast<float>(terrain->height_at(x, z)); };
}

struct Options {
  vox::loadtest::LoadConfig config;
  std::string server, more_servers, websocket, json, svg, sweep, attack, token_key;
  double sweep_limit_ms = 100, max_p99_ms = 0, max_rss_mib = 0;
  vox::loadtest::Limits limits;  // from max_p99_ms and max_rss_mib, when given
};

namespace po = boost::program_options;

void describe(po::options_description& opts, Options& o) {
  opts.add_options()("help,h", "show this help")(
      "server", po::value<std::string>(&o.server)->default_value("127.0.0.1:7777"),
      "HOST:PORT of voxeld (with --websocket: for --verify and --attack only)")(
      "more-servers", po::value<std::string>(&o.more_servers),
      "HOST:PORT,...: more nodes of the same cluster world (docs/CLUSTER.md); the players are "
      "spread over --server and these (player i on the i mod n-th), over TCP")(
      "websocket", po::value<std::string>(&o.websocket),
      "HOST:PORT of voxeld's HTTP port: the players connect over WebSocket (GET /ws, one "
      "Envelope per binary message) instead of TCP; hostile clients (--attack) and the "
      "--verify client stay on TCP (--server)")(
      "players", po::value<int>(&o.config.players)->default_value(20),
      "simulated players (1..10000)")("duration",
                                      po::value<double>(&o.config.duration_s)->default_value(10),
                                      "seconds of play after the ramp")(
      "edit-rate", po::value<double>(&o.config.edit_rate)->default_value(0.5),
      "edits per second per player")(
      "view-radius", po::value<uint32_t>(&o.config.view_radius)->default_value(4),
      "view radius in chunks (with --lod-level: how far level 0 reaches)")(
      "lod-level", po::value<uint32_t>(&o.config.lod_level)->default_value(0),
      "a level-of-detail view of levels 0..N (6: to 2,048 voxels and more); 0: level 0 only")(
      "lod-distance", po::value<float>(&o.config.lod_distance)->default_value(1.0f),
      "with --lod-level: split coarse chunks within this many of their sides")(
      "ramp", po::value<double>(&o.config.ramp_s)->default_value(2),
      "seconds over which players join")("seed",
                                         po::value<uint64_t>(&o.config.seed)->default_value(1),
                                         "seed of the players' paths and edits")(
      "spawn-area", po::value<double>(&o.config.spawn_area)->default_value(0),
      "players live within +-this many voxels of the origin; 0 = grow with --players at the "
      "density of 50 in +-96")("threads", po::value<int>(&o.config.threads)->default_value(0),
                               "event-loop threads (0 = one per core)")(
      "decode-all", po::bool_switch(&o.config.decode_all),
      "every player decodes every mesh itself (by default a version already decoded "
      "byte-identically is not decoded again)")(
      "reconnect", po::bool_switch(&o.config.reconnect),
      "a player whose connection closes (its node died) connects to the next of --server and "
      "--more-servers, sends its view again and resends unanswered edits with their edit ids; "
      "reports the time to reconnect and to the view complete again")(
      "verify", po::bool_switch(&o.config.verify),
      "at the end, check every player's meshes against a fresh client")(
      "json", po::value<std::string>(&o.json), "write the results as JSON to this file")(
      "svg", po::value<std::string>(&o.svg),
      "write latency and throughput over time as SVG to this file")(
      "sweep", po::value<std::string>(&o.sweep),
      "N1,N2,...: run once per player count (1..10000 each); --svg then draws p99 against "
      "players; exits 1 when a run had errors or no count met --sweep-limit-ms")(
      "sweep-limit-ms", po::value<double>(&o.sweep_limit_ms)->default_value(100),
      "the p99 limit the sweep reports against")(
      "attack", po::value<std::string>(&o.attack),
      "MIX of hostile clients beside the players, KIND:COUNT,... with KIND flood, heavy, "
      "squat (a group of 32 sockets), slow or empty and COUNT 0..1000; counted apart, never "
      "in the exit code")(
      "spread-addresses", po::bool_switch(&o.config.spread_addresses),
      "each player and hostile client connects from its own loopback address (127.1.x.y, "
      "127.2.x.y and up by kind), as separate machines would; the server must be on 127.0.0.1")(
      "server-pid", po::value<int>(&o.config.server_pid)->default_value(0),
      "voxeld's pid, to sample its RSS every second (0: find the process listening on the "
      "port when the server is on loopback; -1: do not sample)")(
      "max-p99-ms", po::value<double>(&o.max_p99_ms),
      "exit 1 when the edit -> delta p99 of any minute of the run is above this (a soak's "
      "goal; drawn in the --svg chart)")(
      "max-rss", po::value<double>(&o.max_rss_mib),
      "exit 1 when voxeld's RSS (sampled every second, see --server-pid) is above this many "
      "MiB in any minute")(
      "token-key", po::value<std::string>(&o.token_key),
      "PRIVATE_KEY_FILE (voxel-cli keygen's NAME.key): each player sends its own signed token "
      "(player id sim-N, role player), for a voxeld started with --auth-public-key");
}

// Exit code 2 with a line, for a usage error.
int usage(const std::string& message) {
  std::cerr << "voxel-loadtest: " << message << "\n";
  return 2;
}

// The soak limits: each must be positive; --max-rss needs the RSS and --sweep takes neither
// (its runs are judged by --sweep-limit-ms).
std::optional<int> check_limits(const po::variables_map& vm, Options& o) {
  if (vm.count("max-p99-ms")) {
    if (!(o.max_p99_ms > 0)) return usage("--max-p99-ms must be > 0");
    o.limits.max_p99_ms = o.max_p99_ms;
  }
  if (vm.count("max-rss")) {
    if (!(o.max_rss_mib > 0) || o.config.server_pid == -1)
      return usage("--max-rss must be > 0 MiB, and needs voxeld's RSS (not --server-pid -1)");
    o.limits.max_rss_mib = o.max_rss_mib;
  }
  if (vm.count("sweep") && (o.limits.max_p99_ms || o.limits.max_rss_mib))
    return usage("--sweep takes --sweep-limit-ms, not --max-p99-ms or --max-rss");
  return std::nullopt;
}

std::optional<int> check(const po::variables_map& vm, Options& o) {
  const auto& c = o.config;
  if (c.players < 1 || c.players > 10000 || !(c.duration_s > 0) || !(c.edit_rate > 0) ||
      !(c.ramp_s >= 0) || c.view_radius > 64 || c.lod_level > 20 || !(c.lod_distance >= 1) ||
      c.lod_distance > 64 || !(c.spawn_area >= 0) || c.spawn_area > 1e6 || c.threads < 0 ||
      c.threads > 64) {
    return usage(
        "--players 1..10000, --duration > 0, --edit-rate > 0, --ramp >= 0, --view-radius <= 64, "
        "--lod-level <= 20, --lod-distance 1..64, "
        "--spawn-area 0..1e6, --threads 0..64");
  }
  if (vm.count("attack")) {
    auto mix = vox::loadtest::parse_attack_mix(o.attack);
    if (!mix) return usage("--attack: " + mix.error());
    o.config.attack = *mix;
  }
  if (c.server_pid < -1) return usage("--server-pid is a pid, 0 or -1");
  if (auto code = check_limits(vm, o)) return code;
  if (vm.count("token-key")) {
    try {
      o.config.token_key = vox::auth::read_private_key_file(o.token_key);
    } catch (const std::exception& e) {
      return usage(std::string("--token-key: ") + e.what());
    }
  }
  if (vm.count("sweep") && !(o.sweep_limit_ms > 0)) return usage("--sweep-limit-ms must be > 0");
  return std::nullopt;
}

// --websocket HOST:PORT, HOST an IP address (the players connect to it as given).
void parse_websocket(Options& o) {
  const std::string bad =
      "--websocket must be IP:PORT with a port 1..65535, got '" + o.websocket + "'";
  std::pair<std::string, uint16_t> hp;
  try {
    hp = vox::options::parse_server(o.websocket);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(bad);
  }
  boost::system::error_code ec;
  boost::asio::ip::make_address(hp.first, ec);
  if (ec) throw std::invalid_argument(bad);
  o.config.ws_host = hp.first;
  o.config.ws_port = hp.second;
}

// The command line into `o`; an exit code when no run should start (0: --help, 2: usage).
std::optional<int> parse(int argc, char** argv, Options& o) {
  po::options_description opts("voxel-loadtest options");
  describe(opts, o);
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, opts), vm);
    if (vm.count("help")) {
      std::cout << "usage: voxel-loadtest [options]\n" << opts;
      return 0;
    }
    po::notify(vm);
    const auto [host, port] = vox::options::parse_server(o.server);
    o.config.host = host;
    o.config.port = port;
    if (vm.count("websocket")) parse_websocket(o);
    for (size_t at = 0; !o.more_servers.empty() && at <= o.more_servers.size();) {
      const size_t comma = std::min(o.more_servers.find(',', at), o.more_servers.size());
      o.config.more_servers.push_back(
          vox::options::parse_server(o.more_servers.substr(at, comma - at)));
      at = comma + 1;
    }
    if (!o.config.more_servers.empty() && vm.count("websocket"))
      throw std::invalid_argument("--more-servers takes TCP nodes, not --websocket");
    const bool more_local = std::all_of(o.config.more_servers.begin(), o.config.more_servers.end(),
                                        [](const auto& s) { return s.first == "127.0.0.1"; });
    if (o.config.spread_addresses && (host != "127.0.0.1" || !more_local ||
                                      (o.config.ws_port && o.config.ws_host != "127.0.0.1")))
      throw std::invalid_argument(
          "--spread-addresses needs --server (and --websocket) 127.0.0.1:PORT");
  } catch (const std::exception& e) {
    return usage(std::string(e.what()) + " (see --help)");
  }
  o.config.progress_tty = ::isatty(STDERR_FILENO) != 0;
  return check(vm, o);
}

int run_sweep(const Options& o) {
  const auto counts = vox::loadtest::parse_sweep_counts(o.sweep);
  if (!counts) return usage("--sweep: " + counts.error());
  const auto result =
      vox::loadtest::run_sweep(o.config, *counts, o.sweep_limit_ms, std::cerr, std::cout);
  if (!o.svg.empty()) {
    std::ofstream out(o.svg);
    vox::loadtest::write_sweep_svg(result.points, o.sweep_limit_ms, out);
  }
  return result.any_errors || result.best == 0 ? 1 : 0;
}

// One run: the table, JSON and SVG; exit 1 on any error or broken limit.
int run_once(const Options& o) {
  vox::loadtest::LoadTest test(o.config);
  const vox::loadtest::LoadStats stats = test.run(std::cerr);
  vox::loadtest::write_table(stats, std::cout);
  if (!o.json.empty()) {
    std::ofstream out(o.json);
    vox::loadtest::write_json(stats, out);
  }
  if (!o.svg.empty()) {
    std::ofstream out(o.svg);
    vox::loadtest::write_svg(stats, o.limits.max_p99_ms, out);
  }
  const auto breaches = vox::loadtest::limit_breaches(vox::loadtest::timeline(stats), o.limits);
  for (const auto& line : breaches) std::cerr << "voxel-loadtest: " << line << "\n";
  if (o.limits.max_rss_mib && stats.server_rss_kib.empty()) {
    std::cerr << "voxel-loadtest: --max-rss: voxeld's RSS could not be sampled (give "
                 "--server-pid)\n";
    return 1;
  }
  const bool ok = stats.error_count() == 0 && stats.disconnect_count() == 0 &&
                  stats.decode_failures == 0 && stats.verify_mismatches == 0 &&
                  stats.players_connected == o.config.players && breaches.empty();
  return ok ? 0 : 1;
}

int run(int argc, char** argv) {
  Options o;
  o.config.ground = ground_for_seed;
  if (auto code = parse(argc, argv, o)) return *code;
  return o.sweep.empty() ? run_once(o) : run_sweep(o);
}
}  // namespace

int main(int argc, char** argv) {
  // A server that refuses or drops the verifying client, say, ends the run with one line
  // and exit code 1, not an abort.
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "voxel-loadtest: " << e.what() << "\n";
    return 1;
  }
}
