// The load test: N simulated players on one Asio event loop (no thread per player), each
// walking over the terrain, updating its view and editing near itself and near others.
#pragma once

#include <chrono>
#include <iosfwd>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "client-cli/chunk_cache.hpp"
#include "loadtest/load_stats.hpp"
#include "server/net/asio.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::loadtest {

struct LoadConfig {
  std::string host = "127.0.0.1";
  uint16_t port = 7777;
  int players = 20;
  double duration_s = 10;
  double edit_rate = 0.5;  // edits per second per player
  uint32_t view_radius = 4;
  double ramp_s = 2;
  uint64_t seed = 1;
  double walk_speed = 1.4;   // voxels per second
  double spawn_area = 96;    // players start within +-this many voxels of the origin
  bool verify = false;
  bool progress_tty = false;  // rewrite one progress line instead of printing lines
};

class SimPlayer;

class LoadTest {
 public:
  explicit LoadTest(LoadConfig config);
  ~LoadTest();
  // Runs the whole test; progress lines go to `progress`. Returns the stats.
  LoadStats run(std::ostream& progress);

  // For players (event-loop thread only).
  boost::asio::io_context& io() { return io_; }
  const LoadConfig& config() const { return config_; }
  LoadStats& stats() { return stats_; }
  double now_s() const;  // since the start of the test
  bool editing() const { return editing_; }
  bool stopping() const { return stopping_; }
  // A random player's position, for edits near others.
  std::array<float, 3> someone_elses_position(int self, std::mt19937& rng) const;
  float terrain_height(float x, float z);
  void set_world_seed(uint64_t seed);
  proto::ZstdCodec& zstd() { return zstd_; }
  proto::CodecScratch& scratch() { return scratch_; }
  mesh::ChunkMesh& decoded() { return decoded_; }
  void count_bytes(size_t n);

 private:
  void tick_progress(std::ostream& progress);
  void verify_all();

  LoadConfig config_;
  boost::asio::io_context io_;
  std::vector<std::shared_ptr<SimPlayer>> players_;
  LoadStats stats_;
  std::chrono::steady_clock::time_point start_;
  bool editing_ = false, stopping_ = false;
  std::unique_ptr<world::TerrainGenerator> terrain_;
  proto::ZstdCodec zstd_;
  proto::CodecScratch scratch_;
  mesh::ChunkMesh decoded_;
  uint64_t last_progress_edits_ = 0;
};

}  // namespace vox::loadtest
