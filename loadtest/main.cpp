// voxel-loadtest: thin entry point; the simulation lives in the voxel_loadtest library.
#include <unistd.h>

#include <boost/program_options.hpp>
#include <fstream>
#include <iostream>
#include <sstream>

#include "client-cli/cli_options.hpp"
#include "loadtest/load_test.hpp"
#include "loadtest/player_tokens.hpp"
#include "loadtest/report_svg.hpp"
#include "loadtest/sweep.hpp"
#include "loadtest/timeline.hpp"
#include "server/world/terrain_generator.hpp"

namespace {
// The simulated players walk on the server's own terrain: the one place the load tester
// knows the world beyond the protocol (the library does not; docs/ARCHITECTURE.md).
vox::loadtest::GroundHeight ground_for_seed(uint64_t seed) {
  auto terrain = std::make_shared<const vox::world::TerrainGenerator>(seed);
  return [terrain](int x, int z) { return static_cast<float>(terrain->height_at(x, z)); };
}

int run(int argc, char** argv) {
  namespace po = boost::program_options;
  vox::loadtest::LoadConfig config;
  config.ground = ground_for_seed;
  std::string server, json, svg, sweep, attack, token_key;
  double sweep_limit_ms = 100, max_p99_ms = 0, max_rss_mib = 0;
  po::options_description opts("voxel-loadtest options");
  opts.add_options()("help,h", "show this help")(
      "server", po::value<std::string>(&server)->default_value("127.0.0.1:7777"),
      "HOST:PORT of voxeld")("players", po::value<int>(&config.players)->default_value(20),
                             "simulated players (1..10000)")(
      "duration", po::value<double>(&config.duration_s)->default_value(10),
      "seconds of play after the ramp")("edit-rate",
                                        po::value<double>(&config.edit_rate)->default_value(0.5),
                                        "edits per second per player")(
      "view-radius", po::value<uint32_t>(&config.view_radius)->default_value(4),
      "view radius in chunks")("ramp", po::value<double>(&config.ramp_s)->default_value(2),
                               "seconds over which players join")(
      "seed", po::value<uint64_t>(&config.seed)->default_value(1),
      "seed of the players' paths and edits")(
      "spawn-area", po::value<double>(&config.spawn_area)->default_value(0),
      "players live within +-this many voxels of the origin; 0 = grow with --players at the "
      "density of 50 in +-96")("threads", po::value<int>(&config.threads)->default_value(0),
                               "event-loop threads (0 = one per core)")(
      "decode-all", po::bool_switch(&config.decode_all),
      "every player decodes every mesh itself (by default a version already decoded "
      "byte-identically is not decoded again)")(
      "verify", po::bool_switch(&config.verify),
      "at the end, check every player's meshes against a fresh client")(
      "json", po::value<std::string>(&json), "write the results as JSON to this file")(
      "svg", po::value<std::string>(&svg),
      "write latency and throughput over time as SVG to this file")(
      "sweep", po::value<std::string>(&sweep),
      "N1,N2,...: run once per player count (1..10000 each); --svg then draws p99 against "
      "players; exits 1 when a run had errors or no count met --sweep-limit-ms")(
      "sweep-limit-ms", po::value<double>(&sweep_limit_ms)->default_value(100),
      "the p99 limit the sweep reports against")(
      "attack", po::value<std::string>(&attack),
      "MIX of hostile clients beside the players, KIND:COUNT,... with KIND flood, heavy, "
      "squat (a group of 32 sockets), slow or empty and COUNT 0..1000; counted apart, never "
      "in the exit code")(
      "spread-addresses", po::bool_switch(&config.spread_addresses),
      "each player and hostile client connects from its own loopback address (127.1.x.y, "
      "127.2.x.y and up by kind), as separate machines would; the server must be on 127.0.0.1")(
      "server-pid", po::value<int>(&config.server_pid)->default_value(0),
      "voxeld's pid, to sample its RSS every second (0: find the process listening on the "
      "port when the server is on loopback; -1: do not sample)")(
      "max-p99-ms", po::value<double>(&max_p99_ms),
      "exit 1 when the edit -> delta p99 of any minute of the run is above this (a soak's "
      "goal; drawn in the --svg chart)")(
      "max-rss", po::value<double>(&max_rss_mib),
      "exit 1 when voxeld's RSS (sampled every second, see --server-pid) is above this many "
      "MiB in any minute")(
      "token-key", po::value<std::string>(&token_key),
      "PRIVATE_KEY_FILE (voxel-cli keygen's NAME.key): each player sends its own signed token "
      "(player id sim-N, role player), for a voxeld started with --auth-public-key");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, opts), vm);
    if (vm.count("help")) {
      std::cout << "usage: voxel-loadtest [options]\n" << opts;
      return 0;
    }
    po::notify(vm);
    const auto [host, port] = vox::cli::parse_server(server);
    config.host = host;
    config.port = port;
    if (config.spread_addresses && host != "127.0.0.1")
      throw std::invalid_argument("--spread-addresses needs --server 127.0.0.1:PORT");
  } catch (const std::exception& e) {
    std::cerr << "voxel-loadtest: " << e.what() << " (see --help)\n";
    return 2;
  }
  if (config.players < 1 || config.players > 10000 || !(config.duration_s > 0) ||
      !(config.edit_rate > 0) || !(config.ramp_s >= 0) || config.view_radius > 64 ||
      !(config.spawn_area >= 0) || config.spawn_area > 1e6 || config.threads < 0 ||
      config.threads > 64) {
    std::cerr << "voxel-loadtest: --players 1..10000, --duration > 0, --edit-rate > 0, --ramp >= "
                 "0, --view-radius <= 64, "
                 "--spawn-area 0..1e6, --threads 0..64\n";
    return 2;
  }
  if (vm.count("attack")) {
    auto mix = vox::loadtest::parse_attack_mix(attack);
    if (!mix) {
      std::cerr << "voxel-loadtest: --attack: " << mix.error() << "\n";
      return 2;
    }
    config.attack = *mix;
  }
  vox::loadtest::Limits limits;
  if (vm.count("max-p99-ms")) {
    if (!(max_p99_ms > 0)) {
      std::cerr << "voxel-loadtest: --max-p99-ms must be > 0\n";
      return 2;
    }
    limits.max_p99_ms = max_p99_ms;
  }
  if (vm.count("max-rss")) {
    if (!(max_rss_mib > 0) || config.server_pid == -1) {
      std::cerr << "voxel-loadtest: --max-rss must be > 0 MiB, and needs voxeld's RSS (not "
                   "--server-pid -1)\n";
      return 2;
    }
    limits.max_rss_mib = max_rss_mib;
  }
  if (config.server_pid < -1) {
    std::cerr << "voxel-loadtest: --server-pid is a pid, 0 or -1\n";
    return 2;
  }
  if (vm.count("token-key")) {
    try {
      config.token_key = vox::auth::read_private_key_file(token_key);
    } catch (const std::exception& e) {
      std::cerr << "voxel-loadtest: --token-key: " << e.what() << "\n";
      return 2;
    }
  }
  config.progress_tty = ::isatty(STDERR_FILENO) != 0;
  if (vm.count("sweep")) {
    if (!(sweep_limit_ms > 0)) {
      std::cerr << "voxel-loadtest: --sweep-limit-ms must be > 0\n";
      return 2;
    }
    const auto counts = vox::loadtest::parse_sweep_counts(sweep);
    if (!counts) {
      std::cerr << "voxel-loadtest: --sweep: " << counts.error() << "\n";
      return 2;
    }
    const auto result =
        vox::loadtest::run_sweep(config, *counts, sweep_limit_ms, std::cerr, std::cout);
    if (!svg.empty()) {
      std::ofstream out(svg);
      vox::loadtest::write_sweep_svg(result.points, sweep_limit_ms, out);
    }
    return result.any_errors || result.best == 0 ? 1 : 0;
  }
  vox::loadtest::LoadTest test(config);
  const vox::loadtest::LoadStats stats = test.run(std::cerr);
  vox::loadtest::write_table(stats, std::cout);
  if (!json.empty()) {
    std::ofstream out(json);
    vox::loadtest::write_json(stats, out);
  }
  if (!svg.empty()) {
    std::ofstream out(svg);
    vox::loadtest::write_svg(stats, limits.max_p99_ms, out);
  }
  const auto breaches = vox::loadtest::limit_breaches(vox::loadtest::timeline(stats), limits);
  for (const auto& line : breaches) std::cerr << "voxel-loadtest: " << line << "\n";
  if (limits.max_rss_mib && stats.server_rss_kib.empty()) {
    std::cerr << "voxel-loadtest: --max-rss: voxeld's RSS could not be sampled (give "
                 "--server-pid)\n";
    return 1;
  }
  const bool ok = stats.error_count() == 0 && stats.disconnect_count() == 0 &&
                  stats.decode_failures == 0 && stats.verify_mismatches == 0 &&
                  stats.players_connected == config.players && breaches.empty();
  return ok ? 0 : 1;
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
