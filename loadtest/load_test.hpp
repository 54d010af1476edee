// The load test: N simulated players on one Asio event loop (no thread per player), each
// walking over the terrain, updating its view and editing near itself and near others.
// The loop is run by a few threads (one per core by default); each player's handlers run
// on its own strand, so a player is never entered twice at once, and the shared tallies
// below are thread-safe.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <iosfwd>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "client/asio.hpp"
#include "client/chunk_cache.hpp"
#include "loadtest/attack_mix.hpp"
#include "loadtest/attack_stats.hpp"
#include "loadtest/decode_memo.hpp"
#include "loadtest/host_sampler.hpp"
#include "loadtest/load_stats.hpp"
#include "loadtest/server_sampler.hpp"
#include "server/auth/player_token.hpp"

namespace vox::client {
class Client;
}  // namespace vox::client

namespace vox::loadtest {

// The ground the players walk on: the surface height at voxel column (x, z). The load
// tester is a client and knows no terrain; whoever runs it supplies the ground for the
// seed the server's Welcome names (voxel-loadtest's main uses the server's generator).
using GroundHeight = std::function<float(int x, int z)>;
using GroundForSeed = std::function<GroundHeight(uint64_t seed)>;

struct LoadConfig {
  std::string host = "127.0.0.1";
  uint16_t port = 7777;
  // --websocket: the players connect to ws://ws_host:ws_port/ws (voxeld's HTTP port)
  // instead of the TCP port above, which the verifier and the attackers still use. 0: TCP.
  std::string ws_host;
  uint16_t ws_port = 0;
  // --more-servers (nodes of one cluster world, over TCP): player i connects to the i mod
  // (1 + n)-th of host:port and these; the verifier and the attackers use host:port.
  std::vector<std::pair<std::string, uint16_t>> more_servers;
  // --reconnect: a player whose connection closes connects to the next of host:port and
  // more_servers, sends Hello and its view again, and resends its unanswered edits with
  // their edit ids (PROTOCOL 4.4); edits carry edit ids.
  bool reconnect = false;
  int players = 20;
  double duration_s = 10;
  double edit_rate = 0.5;  // edits per second per player
  uint32_t view_radius = 4;
  // Level of detail (PROTOCOL 4.10): > 0 views levels 0 .. lod_level, level 0 within
  // view_radius chunks; coarse chunks are decoded and held like level-0 ones.
  uint32_t lod_level = 0;
  float lod_distance = 1.0f;
  double ramp_s = 2;
  uint64_t seed = 1;
  double walk_speed = 1.4;  // voxels per second
  // Players start and walk within +-this many voxels of the origin; 0 = scale with the
  // player count so the density stays that of 50 players in +-96 (see spawn_half_width).
  double spawn_area = 0;
  int threads = 0;          // event-loop threads; 0 = one per core
  bool decode_all = false;  // every player decodes every mesh (no DecodeMemo)
  bool verify = false;
  bool progress_tty = false;  // rewrite one progress line instead of printing lines
  // Hostile clients beside the players (--attack); counted apart, never in the exit code.
  AttackMix attack;
  // voxeld's pid for its RSS over the run; 0: look for the process listening on the
  // server's port when the server is on this machine's loopback, -1: do not sample.
  int server_pid = 0;
  // Each player, and each hostile client, connects from its own loopback address
  // (127.1.x.y for players, 127.(2+k).x.y for attackers of kind k), so the server's
  // per-address caps and budgets see them as the distinct machines they stand for.
  // Needs a server on 127.0.0.1.
  bool spread_addresses = false;
  // --token-key: each player's Hello carries its own signed token ("sim-<n>", role
  // player; loadtest/player_tokens.hpp), minted before the run, for a server started with
  // --auth-public-key. nullopt: no tokens (an open server). Attackers never send one.
  std::optional<auth::SecretSeed> token_key;
  // The terrain's heights for a seed; empty: players walk at height 0.
  GroundForSeed ground;
};

// The loopback address a spread player or attacker connects from (see spread_addresses).
// `kind` 0 is the players; attackers use 1 + their kind's index.
std::string spread_source_address(int kind, int client);

// The half-width of the square players live in: --spawn-area, or for 0 one that keeps the
// density of 50 players in +-96 voxels (about 70 players within a radius-4 view).
double spawn_half_width(const LoadConfig& config);

class SimPlayer;
class Attacker;

class LoadTest {
 public:
  explicit LoadTest(LoadConfig config);
  ~LoadTest();
  // Runs the whole test; progress lines go to `progress`. Returns the stats.
  LoadStats run(std::ostream& progress);

  // For players; all of these may be called from any event-loop thread.
  boost::asio::io_context& io() { return io_; }
  const LoadConfig& config() const { return config_; }
  double half_width() const { return half_width_; }
  double now_s() const;  // since the start of the test
  bool editing() const { return editing_.load(std::memory_order_relaxed); }
  bool stopping() const { return stopping_.load(std::memory_order_relaxed); }
  // A random player's position, for edits near others.
  std::array<float, 3> someone_elses_position(int self, std::mt19937& rng) const;
  // Any player's position (attackers aim at the players); the origin before they exist.
  std::array<float, 3> random_player_position(std::mt19937& rng) const;
  float terrain_height(float x, float z) const;
  // The world seed from a Welcome: the first sets the ground the players walk on (from
  // LoadConfig::ground); a different one later is an error (returns false).
  bool set_world_seed(uint64_t seed);
  DecodeMemo* decode_memo() { return config_.decode_all ? nullptr : &memo_; }
  // Player `id`'s token for its Hello; empty without LoadConfig::token_key.
  const std::string& player_token(int id) const;

  // Tallies (thread-safe).
  void record_connected();
  void record_edit_sent();
  // `refusal`: the EditResult status name, empty when accepted.
  void record_result(double sent_s, double now_s, const std::string& refusal);
  void record_delta(double sent_s, double now_s);
  void record_first_view(double ms);
  // --reconnect: from the connection's close to the next Welcome, and to its first
  // complete view; an unanswered edit sent again (answered already_applied or not).
  void record_reconnect(double ms);
  void record_reconnect_view(double ms);
  void record_resent();
  void record_already_applied();
  void record_error(const std::string& cause);
  void record_disconnect(const std::string& cause);
  void count_message() { messages_.fetch_add(1, std::memory_order_relaxed); }
  void count_chunk() { chunks_.fetch_add(1, std::memory_order_relaxed); }
  void count_decode_failure() { decode_failures_.fetch_add(1, std::memory_order_relaxed); }
  void count_bytes(size_t n);
  AttackTally& attack_tally() { return attack_tally_; }  // any thread

 private:
  void start_players();
  void start_attackers();  // after start_players: attackers aim at the players
  void stop_attackers();
  void tick_progress(std::ostream& progress);
  void verify_all();
  size_t lod_mismatches(const SimPlayer& p, const client::Client& fresh) const;
  bool all_views_ready() const;  // any thread
  void collect_counters();
  void sample_machine();  // voxeld, this process and the host, once a second

  LoadConfig config_;
  double half_width_;
  boost::asio::io_context io_;
  std::vector<std::shared_ptr<SimPlayer>> players_;
  std::vector<std::shared_ptr<Attacker>> attackers_;  // fixed once started, like players_
  AttackTally attack_tally_;
  ServerSampler server_;  // main thread only
  HostSampler host_;      // main thread only
  std::chrono::steady_clock::time_point start_;
  std::atomic<bool> editing_{false}, stopping_{false};
  DecodeMemo memo_;
  std::vector<std::string> tokens_;  // per player, and the verifier's last; set before run()

  mutable std::mutex mutex_;  // guards stats_ (but the counters below) and ground_ creation
  LoadStats stats_;
  std::unique_ptr<GroundHeight> ground_owner_;
  uint64_t world_seed_ = 0;  // written before ground_ is published
  std::atomic<const GroundHeight*> ground_{nullptr};
  std::atomic<uint64_t> messages_{0}, bytes_{0}, chunks_{0}, decode_failures_{0};
  std::vector<std::atomic<uint64_t>> bytes_per_second_;  // sized for the whole run up front
  uint64_t last_progress_edits_ = 0;
  size_t last_progress_delta_ = 0;  // edit_to_delta samples already in a progress line
};

}  // namespace vox::loadtest
