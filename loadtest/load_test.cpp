#include "loadtest/load_test.hpp"

#include <cstdio>
#include <ostream>

#include "client-cli/voxel_client.hpp"
#include "loadtest/sim_player.hpp"

namespace vox::loadtest {

namespace asio = boost::asio;
using namespace std::chrono_literals;

LoadTest::LoadTest(LoadConfig config) : config_(std::move(config)) { stats_.players = config_.players; }
LoadTest::~LoadTest() = default;

double LoadTest::now_s() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

std::array<float, 3> LoadTest::someone_elses_position(int self, std::mt19937& rng) const {
  if (players_.size() < 2) return players_[static_cast<size_t>(self)]->position();
  const auto other = std::uniform_int_distribution<size_t>(0, players_.size() - 1)(rng);
  return players_[other == static_cast<size_t>(self) ? (other + 1) % players_.size() : other]->position();
}

void LoadTest::set_world_seed(uint64_t seed) {
  if (!terrain_ || terrain_->seed() != seed) terrain_ = std::make_unique<world::TerrainGenerator>(seed);
}

float LoadTest::terrain_height(float x, float z) {
  if (!terrain_) return 0;
  return terrain_->height_at(static_cast<int>(std::floor(x)), static_cast<int>(std::floor(z))) + 0.5f;
}

void LoadTest::count_bytes(size_t n) {
  stats_.bytes_received += n;
  const auto second = static_cast<size_t>(std::max(0.0, now_s()));
  if (stats_.bytes_per_second.size() <= second) stats_.bytes_per_second.resize(second + 1, 0);
  stats_.bytes_per_second[second] += static_cast<double>(n);
}

void LoadTest::tick_progress(std::ostream& progress) {
  const auto p99 = percentiles([this] {
    std::vector<double> v;
    for (const auto& s : stats_.edit_to_delta) v.push_back(s.ms);
    return v;
  }());
  char line[256];
  std::snprintf(line, sizeof line, "[%5.1f s] players %d/%d connected, %llu edits/s, edit->delta p99 %.1f ms, errors %llu",
                now_s(), stats_.players_connected, config_.players,
                static_cast<unsigned long long>(stats_.edits_sent - last_progress_edits_), p99.p99,
                static_cast<unsigned long long>(stats_.error_count() + stats_.disconnect_count()));
  last_progress_edits_ = stats_.edits_sent;
  progress << (config_.progress_tty ? "\r" : "") << line << (config_.progress_tty ? "" : "\n") << std::flush;
}

LoadStats LoadTest::run(std::ostream& progress) {
  start_ = std::chrono::steady_clock::now();
  std::mt19937 seeds(static_cast<uint32_t>(config_.seed));
  for (int i = 0; i < config_.players; ++i) players_.push_back(std::make_shared<SimPlayer>(*this, i, seeds()));
  // Ramp: players join evenly over --ramp seconds.
  std::vector<std::unique_ptr<asio::steady_timer>> joins;
  for (int i = 0; i < config_.players; ++i) {
    const double at = config_.players > 1 ? config_.ramp_s * i / (config_.players - 1) : 0;
    auto t = std::make_unique<asio::steady_timer>(io_, std::chrono::microseconds(static_cast<int64_t>(at * 1e6)));
    t->async_wait([p = players_[static_cast<size_t>(i)]](boost::system::error_code ec) {
      if (!ec) p->start();
    });
    joins.push_back(std::move(t));
  }
  editing_ = true;
  const double end = config_.ramp_s + config_.duration_s;
  while (now_s() < end) {
    io_.run_for(std::chrono::milliseconds(1000));
    tick_progress(progress);
  }
  editing_ = false;
  stats_.duration_s = now_s();
  const double drain_until = now_s() + 3.0;  // results and meshes of the last edits
  while (now_s() < drain_until) io_.run_for(std::chrono::milliseconds(250));
  if (config_.progress_tty) progress << "\n";
  if (config_.verify) verify_all();
  stopping_ = true;
  for (auto& p : players_) p->close();
  io_.run_for(std::chrono::milliseconds(500));
  return stats_;
}

// Every player's chunks must equal what a fresh client receives for the same view.
void LoadTest::verify_all() {
  stats_.verified = true;
  for (const auto& p : players_) {
    if (!p->connected()) continue;
    client::Client fresh;
    fresh.connect(config_.host, config_.port, 5s);
    fresh.handshake("verifier", 10s);
    const auto at = p->view_position();
    fresh.send(client::make_set_view(at[0], at[1], at[2], p->radius()));
    for (bool first = true;; first = false) {
      auto m = fresh.receive(first ? 15000ms : 700ms);
      if (!m) break;
      if (m->has_chunk_mesh() && fresh.apply(m->chunk_mesh())) ++stats_.verify_mismatches;
    }
    const auto& mine = p->cache().chunks();
    for (const auto& [key, held] : fresh.chunks()) {
      auto it = mine.find(key);
      if (it == mine.end() || it->second.version != held.version || it->second.encoding != held.encoding) {
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

}  // namespace vox::loadtest
