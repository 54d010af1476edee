#include "server/daemon/voxeld_flags.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <set>

#include "options/config_file.hpp"
#include "options/option_values.hpp"
#include "server/auth/player_token.hpp"
#include "server/net/address_key.hpp"
#include "server/store/world_store.hpp"

namespace vox::daemon {
namespace {

namespace po = boost::program_options;

// What the flags say before they are checked: the values that do not go straight into a
// part's configuration.
struct RawFlags {
  std::string max_memory, auth_key_file, open_role = "player", log_format = "text";
  long idle_ms = 60000, handshake_ms = 5000, write_ms = 10000, frame_ms = 10000;
  long evict_after_s = 120, lod_remesh_ms = 750;
  double checkpoint_s = 10;
  double history_days = 7;
  int metrics_port = -1;
  std::string http_port = "7780", http_root;
  std::vector<std::string> http_origins;
  std::vector<std::string> http_proxies, tcp_proxies;
};

po::options_description describe(VoxeldConfig& c, RawFlags& r) {
  net::ServerConfig& net = c.net;
  pipeline::PipelineConfig& world = c.world;
  po::options_description opts("voxeld options");
  auto add = opts.add_options();
  add("help,h", "show this help");
  add("config", po::value<std::string>(),
      "read flags from this file: key = value lines, keys as the flags without --; flags "
      "given here win (voxeld --print-config writes one to start from)");
  add("print-config", "write the effective configuration as a file for --config, and exit");
  add("port", po::value<uint16_t>(&net.port)->default_value(7777), "TCP port (0: pick a free one)");
  add("bind", po::value<std::string>(&net.bind)->default_value("127.0.0.1"),
      "address to listen on");
  add("port-file", po::value<std::string>(&c.port_file), "write the bound port to this file");
  add("http-port", po::value<std::string>(&r.http_port)->default_value("7780"),
      "serve the viewer and WebSocket (/ws) on --bind:PORT (0: off; auto: a free port)");
  add("http-port-file", po::value<std::string>(&c.http_port_file),
      "write the HTTP port to this file");
  add("http-root", po::value<std::string>(&r.http_root),
      "the viewer's files (default: web/ beside voxeld's bin/, as the build leaves them)");
  add("http-allow-origin", po::value<std::vector<std::string>>(&r.http_origins)->composing(),
      "a page origin (https://game.example) allowed to open the WebSocket besides the "
      "server's own; repeat for more; * allows any");
  add("http-trusted-proxy", po::value<std::vector<std::string>>(&r.http_proxies)->composing(),
      "the IP address of a proxy in front of the HTTP port (a TLS terminator): its "
      "WebSocket players are the clients its X-Forwarded-For names, each capped by its own "
      "address; repeat for more");
  add("proxy-protocol-from", po::value<std::vector<std::string>>(&r.tcp_proxies)->composing(),
      "the IP address of a proxy in front of the TCP port sending the PROXY protocol v2 "
      "(HAProxy's send-proxy-v2): its connections' players are the clients it names, each "
      "capped by its own address; repeat for more");
  add("metrics-port", po::value<int>(&r.metrics_port),
      "serve Prometheus metrics on /metrics at --bind:PORT (0: a free port)");
  add("metrics-port-file", po::value<std::string>(&c.metrics_port_file),
      "write the metrics port to this file");
  add("seed", po::value<uint64_t>(),
      "world seed: recorded when the world is created (default 1); an existing world must "
      "have it");
  add("world", po::value<std::string>(&c.world_dir)->default_value("world"),
      "the world's directory (SQLite store; created on first start)");
  add("store", po::value<std::string>(&c.store_uri),
      "postgresql://... : keep the world in this PostgreSQL database instead of --world");
  add("cluster", po::value<std::string>(&c.cluster_file),
      "FILE: run as a node of a cluster world, whose PostgreSQL and NATS (and their "
      "passwords) the file names (docs/CLUSTER.md); instead of --world and --store");
  add("checkpoint-interval", po::value<double>(&r.checkpoint_s)->default_value(10),
      "seconds between checkpoints of the changed chunks (sooner past 2,048 chunks or 20,000 "
      "edits); a restart replays the log since the last one");
  add("keep-log", po::bool_switch(&world.history.keep_all),
      "keep every edit in the log (an audit trail; voxel-cli world log) instead of deleting "
      "what a checkpoint includes once it is older than --history-days");
  add("history-days", po::value<double>(&r.history_days)->default_value(7),
      "days of edits the log keeps past its checkpoints: what voxel-cli world history lists "
      "(0: none)");
  add("in-memory", po::bool_switch(&c.in_memory),
      "keep no world on disk: every edit is lost when voxeld stops (benchmarks)");
  add("threads", po::value<int>(&world.threads)->default_value(0),
      "world pipeline threads (0: all cores)");
  add("io-threads", po::value<int>(&c.io_threads)->default_value(1), "network threads");
  add("max-clients", po::value<size_t>(&net.max_clients)->default_value(256),
      "players beyond this are refused (SERVER_FULL)");
  add("max-handshaking", po::value<size_t>(&net.max_handshaking)->default_value(64),
      "connections before Hello (not players) at once");
  add("max-per-address", po::value<size_t>(&net.max_per_address)->default_value(16),
      "connections from one address (0: no cap)");
  add("max-handshaking-per-address",
      po::value<size_t>(&net.max_handshaking_per_address)->default_value(4),
      "of those, before Hello (0: no cap)");
  add("max-memory", po::value<std::string>(&r.max_memory),
      "memory budget for chunks, meshes and sessions, e.g. 2G (default: half the RAM, at most 4G)");
  add("load-budget", po::value<double>(&world.load_work_per_owner)->default_value(250),
      "terrain load work per second per player (4 per chunk generated, 1 per mesh; 0: unlimited)");
  add("load-burst", po::value<double>(&world.load_burst_per_owner)->default_value(8000),
      "load work a player may take at once (a first radius-4 view is 2,925; one to the "
      "horizon, --lod-level 6, about 6,100)");
  add("load-budget-per-address",
      po::value<double>(&world.load_work_per_address)->default_value(1000),
      "load work per second for all players from one address together, burst 8x that; kept "
      "after they leave until refilled (0: unlimited)");
  add("edit-budget", po::value<double>(&net.edit_budget_rate)->default_value(300000),
      "samples per second a player's edits may touch, all its connections together (0: "
      "unlimited; a token's edit_rate overrides it)");
  add("edit-burst", po::value<double>(&net.edit_budget_burst)->default_value(600000),
      "samples a player's edits may touch at once");
  add("admin-edit-budget", po::value<double>(&net.admin_edit_budget_rate)->default_value(0),
      "the same for admins (0: unlimited)");
  add("admin-edit-burst", po::value<double>(&net.admin_edit_budget_burst)->default_value(0),
      "samples an admin's edits may touch at once");
  add("set-view-rate", po::value<double>(&net.set_view_rate)->default_value(2),
      "SetViews per second per player; more are coalesced (0: unlimited)");
  add("publish-at-once", po::bool_switch(&net.publish_at_once),
      "tell every publication to the sessions at once, not gathered while the last is "
      "unhandled (for comparison)");
  add("message-rate", po::value<double>(&net.message_rate)->default_value(200),
      "messages per second per connection before it is read slower (0: unlimited)");
  add("frame-timeout-ms", po::value<long>(&r.frame_ms)->default_value(10000),
      "a started frame must complete within this");
  add("evict-after", po::value<long>(&r.evict_after_s)->default_value(120),
      "seconds before an unused chunk (unmodified, or checkpointed) is evicted");
  add("max-view-radius", po::value<uint32_t>(&net.max_view_radius)->default_value(12),
      "largest view radius in chunks");
  add("max-lod-level", po::value<uint32_t>(&net.max_lod_level)->default_value(6),
      "coarsest level of detail a view may ask for (0: none; level 6 chunks are 2,048 voxels)");
  add("max-lod-distance", po::value<float>(&net.max_lod_distance)->default_value(2.0f),
      "largest SetView.lod_distance (1..4; larger: more coarse chunks per view)");
  add("query-rate", po::value<double>(&net.query_rate)->default_value(20),
      "raycast, ground and sample queries per second per connection, a burst of twice as "
      "many (0: unlimited)");
  add("max-query-distance", po::value<float>(&net.max_query_distance)->default_value(512),
      "longest raycast or ground search in voxels (1..4096)");
  add("lod-remesh-interval-ms", po::value<long>(&r.lod_remesh_ms)->default_value(750),
      "an edited level-1 chunk is re-meshed at most this often, each coarser level half as "
      "often down to 1/8 (10..750; an update reaches players within about this plus a pass)");
  add("idle-timeout-ms", po::value<long>(&r.idle_ms)->default_value(60000),
      "disconnect clients silent this long");
  add("handshake-timeout-ms", po::value<long>(&r.handshake_ms)->default_value(5000),
      "time allowed for Hello");
  add("write-timeout-ms", po::value<long>(&r.write_ms)->default_value(10000),
      "disconnect clients that stop reading");
  add("stats-interval", po::value<int>(&c.stats_seconds)->default_value(10),
      "seconds between stats lines (0: none)");
  add("log-format", po::value<std::string>(&r.log_format)->default_value("text"),
      "text, or json: one JSON object per line (time, level, thread, msg) for log shippers");
  add("log-level", po::value<std::string>(&c.log_level)->default_value("info"),
      "trace, debug, info, warn, error, critical or off");
  add("auth-public-key", po::value<std::string>(&r.auth_key_file),
      "players must present a token signed by this key (voxel-cli keygen writes NAME.pub)");
  add("open-role", po::value<std::string>(&r.open_role)->default_value("player"),
      "without --auth-public-key: every player's role (viewer, player or admin)");
  return opts;
}

// "1".."65535", or nullopt.
std::optional<int> port_number(const std::string& text) {
  if (text.empty() || text.size() > 5 ||
      !std::all_of(text.begin(), text.end(), [](char ch) { return ch >= '0' && ch <= '9'; }))
    return std::nullopt;
  const int port = std::stoi(text);
  return port >= 1 && port <= 65535 ? std::optional<int>(port) : std::nullopt;
}

// The key in `file`, or why not.
std::string read_public_key(const std::string& file, std::optional<auth::PublicKey>& key) {
  auth::init_crypto();
  std::ifstream in(file, std::ios::binary);
  if (!in) return "--auth-public-key " + file + ": cannot be read";
  std::string text(256, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  key = in || in.eof() ? auth::key_from_text(text) : std::nullopt;
  if (key) return {};
  return "--auth-public-key " + file +
         ": not a public key file (one line of base64url, 32 bytes: voxel-cli keygen writes "
         "NAME.pub; NAME.key is the private key and stays on the backend)";
}

// Checks each rule and fills what the raw values set; one message per broken rule.
std::vector<std::string> check(const po::variables_map& vm, const RawFlags& r, VoxeldConfig& c) {
  std::vector<std::string> bad;
  net::ServerConfig& net = c.net;
  pipeline::PipelineConfig& world = c.world;
  const auto rule = [&bad](bool ok, std::string message) {
    if (!ok) bad.push_back(std::move(message));
  };
  const auto range = [&rule](const char* flag, auto value, auto lo, auto hi) {
    rule(value >= lo && value <= hi,
         fmt::format("{} must be {}..{} (got {})", flag, lo, hi, value));
  };
  const auto positive_ms = [&rule](const char* flag, long value) {
    rule(value > 0, fmt::format("{} must be > 0 (got {})", flag, value));
  };
  range("--io-threads", c.io_threads, 1, 64);
  rule(world.threads >= 0, fmt::format("--threads must be >= 0 (got {})", world.threads));
  positive_ms("--idle-timeout-ms", r.idle_ms);
  positive_ms("--handshake-timeout-ms", r.handshake_ms);
  positive_ms("--write-timeout-ms", r.write_ms);
  positive_ms("--frame-timeout-ms", r.frame_ms);
  rule(r.evict_after_s >= 1, fmt::format("--evict-after must be >= 1 (got {})", r.evict_after_s));
  if (vm.count("metrics-port")) range("--metrics-port", r.metrics_port, 0, 65535);
  const std::optional<int> http_port = r.http_port == "auto" ? std::optional<int>(0)
                                       : r.http_port == "0"  ? std::optional<int>(-1)
                                                             : port_number(r.http_port);
  rule(http_port.has_value(),
       "--http-port must be 1..65535, 0 (off) or auto (got '" + r.http_port + "')");
  for (const std::string& origin : r.http_origins) {
    rule(origin == "*" || origin.starts_with("http://") || origin.starts_with("https://"),
         "--http-allow-origin must be * or an origin such as https://game.example (got '" + origin +
             "')");
  }
  std::vector<std::string> proxies;
  for (const std::string& proxy : r.http_proxies) {
    boost::system::error_code ec;
    const auto address = boost::asio::ip::make_address(proxy, ec);
    rule(!ec, "--http-trusted-proxy must be an IP address such as 127.0.0.1 (got '" + proxy + "')");
    if (!ec) proxies.push_back(net::address_text(address));
  }
  for (const std::string& proxy : r.tcp_proxies) {
    boost::system::error_code ec;
    const auto address = boost::asio::ip::make_address(proxy, ec);
    rule(!ec,
         "--proxy-protocol-from must be an IP address such as 127.0.0.1 (got '" + proxy + "')");
    if (!ec) net.tcp_proxies.push_back(net::address_text(address));
  }
  rule(r.history_days >= 0 && r.history_days <= 3650,
       fmt::format("--history-days must be 0..3650 (got {})", r.history_days));
  rule(r.checkpoint_s >= 0.01 && r.checkpoint_s <= 86400,
       fmt::format("--checkpoint-interval must be 0.01..86400 (got {})", r.checkpoint_s));
  // The view radius bounds each session's memory (a ball of radius r holds ~4.2 r^3 chunks).
  range("--max-view-radius", net.max_view_radius, 0u, 32u);
  range("--max-lod-level", net.max_lod_level, 0u, 6u);
  range("--max-lod-distance", net.max_lod_distance, 1.0f, 4.0f);
  range("--lod-remesh-interval-ms", r.lod_remesh_ms, 10L, 750L);
  range("--query-rate", net.query_rate, 0.0, 100000.0);
  range("--max-query-distance", net.max_query_distance, 1.0f, 4096.0f);
  rule(net.max_clients >= 1, "--max-clients must be >= 1");
  rule(net.max_handshaking >= 1, "--max-handshaking must be >= 1");
  // The burst (8x) must hold one work unit, or no view of the address would ever load.
  rule(world.load_work_per_address == 0 || world.load_work_per_address >= 0.125,
       fmt::format("--load-budget-per-address must be 0 (unlimited) or at least 0.125 (got {})",
                   world.load_work_per_address));
  // spdlog reads an unknown name as "off": a typo would silence the server.
  rule(spdlog::level::from_str(c.log_level) != spdlog::level::off || c.log_level == "off",
       "--log-level must be trace, debug, info, warn, error, critical or off (got '" + c.log_level +
           "')");
  // The largest edit (a box of side 2 * max radius, off the integer grid) must fit in the
  // budget's burst.
  const double largest_edit = vox::world::max_touched_samples(world.limits);
  rule(net.edit_budget_rate <= 0 || net.edit_budget_burst >= largest_edit,
       fmt::format("--edit-burst must be at least {} samples (the largest edit)",
                   static_cast<uint64_t>(largest_edit)));
  rule(net.admin_edit_budget_rate <= 0 || net.admin_edit_budget_burst >= largest_edit,
       fmt::format("--admin-edit-burst must be at least {} samples (the largest edit)",
                   static_cast<uint64_t>(largest_edit)));
  rule(r.log_format == "text" || r.log_format == "json",
       "--log-format must be text or json (got '" + r.log_format + "')");
  const auto role = auth::parse_role(r.open_role);
  rule(role.has_value(), "--open-role must be viewer, player or admin (got '" + r.open_role + "')");
  if (!r.auth_key_file.empty()) {
    const std::string why = read_public_key(r.auth_key_file, net.auth_key);
    rule(why.empty(), why);
  }
  const auto bytes = r.max_memory.empty() ? std::optional<size_t>(default_max_memory())
                                          : options::parse_bytes(r.max_memory);
  rule(bytes && *bytes >= (size_t{64} << 20),
       "--max-memory must be bytes with an optional K/M/G suffix, at least 64M (got '" +
           r.max_memory + "')");
  rule(c.store_uri.empty() || store::is_postgres_uri(c.store_uri),
       "--store must be a postgresql:// URI (the default store is --world)");
  rule(c.cluster_file.empty() || (c.store_uri.empty() && !c.in_memory),
       "--cluster keeps the world in the cluster's database: not with --store or --in-memory");
  if (!bad.empty()) return bad;

  net.open_role = *role;
  c.json_logs = r.log_format == "json";
  net.idle_timeout = std::chrono::milliseconds(r.idle_ms);
  net.handshake_timeout = std::chrono::milliseconds(r.handshake_ms);
  net.write_timeout = std::chrono::milliseconds(r.write_ms);
  net.frame_timeout = std::chrono::milliseconds(r.frame_ms);
  world.max_memory = *bytes;
  world.load_burst_per_address = 8 * world.load_work_per_address;
  world.lod.remesh_interval = std::chrono::milliseconds(r.lod_remesh_ms);
  world.evict_after = std::chrono::seconds(r.evict_after_s);
  world.checkpoint.interval = std::chrono::milliseconds(static_cast<long>(r.checkpoint_s * 1000));
  world.history.window =
      std::chrono::milliseconds(static_cast<int64_t>(r.history_days * 86400.0 * 1000.0));
  if (vm.count("seed")) c.seed = vm["seed"].as<uint64_t>();
  world.seed = c.seed.value_or(1);  // a stored world's own seed replaces it when opened
  if (r.metrics_port >= 0) c.metrics_port = static_cast<uint16_t>(r.metrics_port);
  if (*http_port >= 0) {
    net::HttpConfig http;
    http.bind = net.bind;
    http.port = static_cast<uint16_t>(*http_port);
    http.root = r.http_root;
    http.allow_origins = r.http_origins;
    http.trusted_proxies = std::move(proxies);
    http.request_timeout = net.handshake_timeout;
    // The HTTP cap per address follows the game's (a trusted proxy has none).
    http.max_per_address = net::http_per_address_cap(net.max_per_address);
    net.http = std::move(http);
    net.http_port_required = !vm["http-port"].defaulted();
  }
  return bad;
}

}  // namespace

int parse_voxeld_flags(const std::vector<std::string>& args, VoxeldConfig& config,
                       std::ostream& out, std::ostream& err) {
  RawFlags raw;
  const po::options_description opts = describe(config, raw);
  po::variables_map vm;
  const int code =
      options::parse_args("voxeld", args, opts, nullptr, "usage: voxeld [options]", vm, out, err);
  if (code >= 0) return code;
  const std::set<std::string> not_in_file = {"help", "config", "print-config"};
  options::ConfigFile file;
  if (vm.count("config")) {
    std::set<std::string> on_command_line;
    for (const auto& [key, value] : vm)
      if (!value.defaulted()) on_command_line.insert(key);
    file = options::store_config_file(vm["config"].as<std::string>(), opts, not_in_file,
                                      on_command_line, vm);
    for (const std::string& line : file.errors) err << "voxeld: " << line << "\n";
    if (!file.errors.empty()) return 2;
    po::notify(vm);  // the file's values into the configuration
    for (const std::string& key : on_command_line) file.lines.erase(key);
  }
  std::vector<std::string> bad = check(vm, raw, config);
  for (std::string& line : bad) {
    // A rule broken by a value from the file names where it was set.
    const size_t end = line.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789-", 2);
    const auto it =
        line.starts_with("--") ? file.lines.find(line.substr(2, end - 2)) : file.lines.end();
    if (it != file.lines.end()) line += " (" + file.path + ":" + std::to_string(it->second) + ")";
    err << "voxeld: " << line << "\n";
  }
  if (!bad.empty()) return 2;
  config.args = args;
  config.effective = options::effective_values(opts, vm, not_in_file);
  if (vm.count("print-config")) {
    out << "# voxeld configuration: voxeld --config FILE reads it; a flag given with it wins.\n"
           "# A list (http-allow-origin, ...) takes one line per value. Written by "
           "voxeld --print-config.\n";
    options::write_config_file(out, opts, vm, not_in_file);
    return 0;
  }
  return -1;
}

size_t default_max_memory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  const size_t half =
      pages > 0 && page > 0 ? static_cast<size_t>(pages) * page / 2 : size_t{1} << 30;
  return std::min(half, size_t{4} << 30);
}

}  // namespace vox::daemon
