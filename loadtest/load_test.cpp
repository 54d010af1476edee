#include "loadtest/load_test.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <thread>

#include "client/voxel_client.hpp"
#include "loadtest/attacker.hpp"
#include "loadtest/player_tokens.hpp"
#include "loadtest/sim_player.hpp"

namespace vox::loadtest {

namespace asio = boost::asio;
using namespace std::chrono_literals;

namespace {
constexpr double kDrainS = 3.0;  // after the editing stops: results and meshes of the last edits
// The same with level-of-detail views: voxeld re-meshes a coarse chunk at most every 6 s
// (levels 4 and up; PROTOCOL 4.10), so its last edit may reach it that late.
constexpr double kDrainLodS = 8.0;
constexpr double kViewWaitS = 60;       // --verify: longest wait for a view to complete
constexpr int64_t kTokenSlackS = 3600;  // tokens expire this long after the planned end

// --token-key: the players' tokens, then the verifier's (its own player id, so that it
// does not replace a player's connection); none without a key.
std::vector<std::string> tokens_for(const LoadConfig& config) {
  if (!config.token_key) return {};
  const int64_t now = std::chrono::duration_cast<std::chrono::seconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  const int64_t expires_at =
      now + static_cast<int64_t>(std::ceil(config.ramp_s + config.duration_s)) + kTokenSlackS;
  auto tokens = mint_player_tokens(*config.token_key, config.players, expires_at);
  tokens.push_back(auth::mint_token({.player_id = "sim-verifier",
                                     .display_name = "verifier",
                                     .role = auth::Role::kViewer,
                                     .expires_at = expires_at},
                                    *config.token_key));
  return tokens;
}

// The pid whose RSS to sample: --server-pid, else the owner of the listening socket when
// the server is on loopback (best effort: 0, no sampling, when it cannot be found).
int server_pid_of(const LoadConfig& config) {
  if (config.server_pid != 0) return std::max(0, config.server_pid);
  const bool local =
      config.host.rfind("127.", 0) == 0 || config.host == "::1" || config.host == "0.0.0.0";
  return local ? find_listening_pid(config.port).value_or(0) : 0;
}
}  // namespace

double spawn_half_width(const LoadConfig& config) {
  if (config.spawn_area > 0) return config.spawn_area;
  return 96.0 * std::sqrt(std::max(1.0, config.players / 50.0));
}

LoadTest::LoadTest(LoadConfig config)
    : config_(std::move(config)),
      half_width_(spawn_half_width(config_)),
      server_(server_pid_of(config_)),
      tokens_(tokens_for(config_)),
      bytes_per_second_(static_cast<size_t>(config_.ramp_s + config_.duration_s + kDrainLodS) +
                        16) {
  stats_.players = config_.players;
}
LoadTest::~LoadTest() = default;

const std::string& LoadTest::player_token(int id) const {
  static const std::string kNone;
  return tokens_.empty() ? kNone : tokens_.at(static_cast<size_t>(id));
}

double LoadTest::now_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

std::array<float, 3> LoadTest::someone_elses_position(int self, std::mt19937& rng) const {
  if (players_.size() < 2) return players_[static_cast<size_t>(self)]->position();
  const auto other = std::uniform_int_distribution<size_t>(0, players_.size() - 1)(rng);
  return players_[other == static_cast<size_t>(self) ? (other + 1) % players_.size() : other]
      ->position();
}

std::array<float, 3> LoadTest::random_player_position(std::mt19937& rng) const {
  if (players_.empty()) return {0, 0, 0};
  return players_[std::uniform_int_distribution<size_t>(0, players_.size() - 1)(rng)]->position();
}

bool LoadTest::set_world_seed(uint64_t seed) {
  if (ground_.load(std::memory_order_acquire)) return world_seed_ == seed;
  std::lock_guard lock(mutex_);
  if (!ground_owner_) {
    world_seed_ = seed;
    ground_owner_ = std::make_unique<GroundHeight>(config_.ground ? config_.ground(seed) : nullptr);
    ground_.store(ground_owner_.get(), std::memory_order_release);
  }
  return world_seed_ == seed;
}

float LoadTest::terrain_height(float x, float z) const {
  const auto* g = ground_.load(std::memory_order_acquire);
  if (!g || !*g) return 0;
  return (*g)(static_cast<int>(std::floor(x)), static_cast<int>(std::floor(z))) + 0.5f;
}

void LoadTest::record_connected() {
  std::lock_guard lock(mutex_);
  ++stats_.players_connected;
}

void LoadTest::record_edit_sent() {
  std::lock_guard lock(mutex_);
  ++stats_.edits_sent;
}

void LoadTest::record_result(double sent_s, double now_s, const std::string& refusal) {
  std::lock_guard lock(mutex_);
  ++stats_.results;
  if (!refusal.empty()) {
    ++stats_.refused;
    ++stats_.refused_by_status[refusal];
  }
  stats_.edit_to_result.push_back({now_s, (now_s - sent_s) * 1000});
}

void LoadTest::record_delta(double sent_s, double now_s) {
  std::lock_guard lock(mutex_);
  stats_.edit_to_delta.push_back({now_s, (now_s - sent_s) * 1000});
}

void LoadTest::record_first_view(double ms) {
  std::lock_guard lock(mutex_);
  stats_.first_view_ms.push_back(ms);
}

void LoadTest::record_reconnect(double ms) {
  std::lock_guard lock(mutex_);
  stats_.reconnect_ms.push_back(ms);
}

void LoadTest::record_reconnect_view(double ms) {
  std::lock_guard lock(mutex_);
  stats_.reconnect_view_ms.push_back(ms);
}

void LoadTest::record_resent() {
  std::lock_guard lock(mutex_);
  ++stats_.edits_resent;
}

void LoadTest::record_already_applied() {
  std::lock_guard lock(mutex_);
  ++stats_.resent_already_applied;
}

void LoadTest::record_error(const std::string& cause) {
  std::lock_guard lock(mutex_);
  ++stats_.errors[cause];
}

void LoadTest::record_disconnect(const std::string& cause) {
  std::lock_guard lock(mutex_);
  ++stats_.disconnects[cause];
}

void LoadTest::count_bytes(size_t n) {
  bytes_.fetch_add(n, std::memory_order_relaxed);
  const auto second =
      std::min(bytes_per_second_.size() - 1, static_cast<size_t>(std::max(0.0, now_s())));
  bytes_per_second_[second].fetch_add(n, std::memory_order_relaxed);
}

void LoadTest::sample_machine() {
  server_.sample();
  host_.sample();
}

void LoadTest::collect_counters() {
  std::lock_guard lock(mutex_);
  stats_.messages_received = messages_.load();
  stats_.bytes_received = bytes_.load();
  stats_.chunks_streamed = chunks_.load();
  stats_.decode_failures = decode_failures_.load();
  stats_.attack = attack_tally_.snapshot(config_.attack);
  stats_.server_pid = server_.pid();
  stats_.server_rss_kib = server_.kib();
  stats_.server_cpu_percent = server_.cpu_percent();
  stats_.tester_cpu_percent = host_.tester_cpu_percent();
  stats_.host_steal_percent = host_.steal_percent();
  const auto seconds = static_cast<size_t>(std::ceil(now_s()));
  stats_.bytes_per_second.assign(std::min(seconds, bytes_per_second_.size()), 0);
  for (size_t i = 0; i < stats_.bytes_per_second.size(); ++i) {
    stats_.bytes_per_second[i] = static_cast<double>(bytes_per_second_[i].load());
  }
}

void LoadTest::tick_progress(std::ostream& progress) {
  std::vector<double> delta_ms;
  uint64_t edits = 0, errors = 0;
  int connected = 0;
  {
    std::lock_guard lock(mutex_);
    // The last second's: a soak's progress line shows now, not the run so far (and does
    // not copy every sample of an hour each second).
    for (size_t i = last_progress_delta_; i < stats_.edit_to_delta.size(); ++i)
      delta_ms.push_back(stats_.edit_to_delta[i].ms);
    last_progress_delta_ = stats_.edit_to_delta.size();
    edits = stats_.edits_sent;
    errors = stats_.error_count() + stats_.disconnect_count();
    connected = stats_.players_connected;
  }
  char line[256];
  std::snprintf(
      line, sizeof line,
      "[%5.1f s] players %d/%d connected, %llu edits/s, edit->delta p99 %.1f ms (last s), "
      "errors %llu",
      now_s(), connected, config_.players,
      static_cast<unsigned long long>(edits - last_progress_edits_),
      percentiles(std::move(delta_ms)).p99, static_cast<unsigned long long>(errors));
  last_progress_edits_ = edits;
  std::string extra;
  if (!server_.kib().empty())
    extra +=
        ", voxeld RSS " + std::to_string(static_cast<int>(server_.kib().back() / 1024)) + " MiB";
  if (!server_.cpu_percent().empty())
    extra += ", CPU " + std::to_string(static_cast<int>(server_.cpu_percent().back())) + " %";
  if (!config_.attack.empty()) {
    const AttackStats a = attack_tally_.snapshot(config_.attack);
    uint64_t connects = 0, closed = 0;
    for (const auto& k : a.kinds) {
      connects += k.connects;
      closed += k.disconnects;
    }
    extra += ", attackers " + std::to_string(connects) + " connections, " + std::to_string(closed) +
             " closed";
  }
  progress << (config_.progress_tty ? "\r" : "") << line << extra
           << (config_.progress_tty ? "" : "\n") << std::flush;
}

std::string spread_source_address(int kind, int client) {
  const std::string last = std::to_string(client % 254 + 1);  // no .0 or .255
  return "127." + std::to_string(1 + kind) + "." + std::to_string(client / 254 % 256) + "." + last;
}

// Ramp: players join evenly over --ramp seconds, each on its own strand.
void LoadTest::start_players() {
  std::mt19937 seeds(static_cast<uint32_t>(config_.seed));
  for (int i = 0; i < config_.players; ++i)
    players_.push_back(std::make_shared<SimPlayer>(*this, i, seeds()));
  for (int i = 0; i < config_.players; ++i) {
    const double at = config_.players > 1 ? config_.ramp_s * i / (config_.players - 1) : 0;
    auto t = std::make_shared<asio::steady_timer>(
        io_, std::chrono::microseconds(static_cast<int64_t>(at * 1e6)));
    t->async_wait([t, p = players_[static_cast<size_t>(i)]](boost::system::error_code ec) {
      if (!ec) p->start();
    });
  }
}

// Attackers join over the ramp too, interleaved with the players (the first after the
// first player), each on its own strand; squatters are kSquatGroupSize sockets apiece.
void LoadTest::start_attackers() {
  std::mt19937 seeds(static_cast<uint32_t>(config_.seed) ^ 0x5eedu);
  for (AttackKind kind : kAttackKinds) {
    for (int i = 0; i < config_.attack.connections(kind); ++i)
      attackers_.push_back(std::make_shared<Attacker>(*this, kind, i, seeds()));
  }
  std::shuffle(attackers_.begin(), attackers_.end(), seeds);  // kinds arrive mixed
  const auto n = static_cast<double>(attackers_.size());
  for (size_t i = 0; i < attackers_.size(); ++i) {
    const double at = config_.ramp_s * (static_cast<double>(i) + 0.5) / n;
    auto t = std::make_shared<asio::steady_timer>(
        io_, std::chrono::microseconds(static_cast<int64_t>(at * 1e6)));
    t->async_wait([t, a = attackers_[i]](boost::system::error_code ec) {
      if (!ec) a->start();
    });
  }
}

void LoadTest::stop_attackers() {
  for (auto& a : attackers_) a->stop();
}

LoadStats LoadTest::run(std::ostream& progress) {
  start_ = std::chrono::steady_clock::now();
  editing_ = true;
  start_players();
  start_attackers();
  sample_machine();
  auto work = asio::make_work_guard(io_);
  const int thread_count = config_.threads > 0
                               ? config_.threads
                               : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<std::thread> threads;
  for (int i = 0; i < thread_count; ++i) threads.emplace_back([this] { io_.run(); });
  const double end = config_.ramp_s + config_.duration_s;
  for (double next = 1; now_s() < end; next += 1) {
    std::this_thread::sleep_for(
        std::chrono::duration<double>(std::max(0.0, std::min(next, end) - now_s())));
    sample_machine();
    tick_progress(progress);
  }
  editing_ = false;
  stop_attackers();  // the drain measures the players' last edits without attackers
  {
    std::lock_guard lock(mutex_);
    stats_.duration_s = now_s();
  }
  const double drain = config_.lod_level > 0 ? kDrainLodS : kDrainS;
  for (double slept = 0; slept < drain; slept += 1) {
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(1.0, drain - slept)));
    sample_machine();
  }
  // The players stand still now: before verifying, every view must be complete (the
  // server says so with ViewReady), however slowly the server streams.
  for (double waited = 0; config_.verify && waited < kViewWaitS && !all_views_ready();
       waited += 0.1) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  // Freeze the players (no handler runs once the threads are joined) for the verification.
  io_.stop();
  for (auto& t : threads) t.join();
  if (config_.progress_tty) progress << "\n";
  collect_counters();
  if (config_.verify) verify_all();
  stopping_ = true;
  for (auto& p : players_) p->close();
  work.reset();
  io_.restart();
  io_.run_for(std::chrono::milliseconds(500));
  return stats_;
}

bool LoadTest::all_views_ready() const {
  return std::all_of(players_.begin(), players_.end(),
                     [](const auto& p) { return p->view_ready(); });
}

// Every player's chunks must equal what a fresh client receives for the same view.
void LoadTest::verify_all() {
  stats_.verified = true;
  for (const auto& p : players_) {
    if (!p->connected()) continue;
    client::Client fresh;
    fresh.connect(config_.host, config_.port, 5s);
    fresh.handshake("verifier", 10s, tokens_.empty() ? std::string() : tokens_.back());
    const auto at = p->view_position();
    if (!p->view_ready()) {  // the server never completed this player's view
      ++stats_.verify_mismatches;
      continue;
    }
    fresh.send(client::make_set_view(at[0], at[1], at[2], p->radius(), 1, config_.lod_level,
                                     config_.lod_level > 0 ? config_.lod_distance : 0));
    try {
      fresh.receive_view(1, std::chrono::seconds(static_cast<int>(kViewWaitS)));
    } catch (const std::exception&) {  // a view that does not complete or apply
      ++stats_.verify_mismatches;
      continue;
    }
    if (config_.lod_level > 0) {
      stats_.verify_mismatches += lod_mismatches(*p, fresh);
      continue;
    }
    const auto& mine = p->cache().chunks();
    for (const auto& [key, held] : fresh.chunks()) {
      auto it = mine.find(key);
      if (it == mine.end() || it->second.version != held.version ||
          it->second.encoding != held.encoding) {
        ++stats_.verify_mismatches;
      }
    }
    for (const auto& [key, held] : mine) {
      if (fresh.chunks().count(key)) continue;
      // Held but not sent to a fresh client: only right for a mesh without triangles.
      auto decoded = proto::decode_mesh(held.encoding);
      if (!decoded || !decoded->empty()) ++stats_.verify_mismatches;
    }
  }
}

// A LOD view's layout depends on where the player came from (hysteresis), so a fresh
// client's may differ: the chunks both hold must match (level 0: version and encoding;
// coarser: the encoding, when both have the same seams, bytes 16-18 of format 2).
size_t LoadTest::lod_mismatches(const SimPlayer& p, const client::Client& fresh) const {
  size_t bad = 0;
  for (const auto& [key, held] : fresh.chunks()) {
    const auto it = p.cache().chunks().find(key);
    if (it != p.cache().chunks().end() &&
        (it->second.version != held.version || it->second.encoding != held.encoding))
      ++bad;
  }
  for (const auto& [level, cache] : p.lod_caches()) {
    for (const auto& [key, held] : fresh.lod_chunks(level)) {
      const auto it = cache.chunks().find(key);
      if (it == cache.chunks().end()) continue;
      const auto& mine = it->second.encoding;
      const bool same_seams =
          mine.size() > 19 && held.encoding.size() > 19 &&
          std::equal(mine.begin() + 16, mine.begin() + 19, held.encoding.begin() + 16);
      if (same_seams && mine != held.encoding) ++bad;
    }
  }
  return bad;
}

}  // namespace vox::loadtest
