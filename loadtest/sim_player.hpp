// One simulated player: an asynchronous client on the load test's event loop. Its
// connection (a PlayerLink: TCP or WebSocket) and timer live on its own strand, so its
// handlers never run at once on two threads; only its published position is read by
// other players.
#pragma once

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <random>
#include <set>

#include "client/chunk_cache.hpp"
#include "loadtest/load_test.hpp"
#include "loadtest/player_link.hpp"

namespace vox::loadtest {

class SimPlayer : public std::enable_shared_from_this<SimPlayer> {
 public:
  SimPlayer(LoadTest& test, int id, uint32_t seed);
  void start();  // connect, then play (from any thread)
  void close();  // only while the event loop is not running
  int id() const { return id_; }
  bool connected() const { return welcomed_; }
  std::array<float, 3> position() const;  // from any thread
  std::array<float, 3> view_position() const { return view_position_; }
  const client::ChunkCache& cache() const { return cache_; }
  // Level-k chunks held (k >= 1); only while the event loop is not running.
  const std::map<uint32_t, client::ChunkCache>& lod_caches() const { return lod_cache_; }
  uint32_t radius() const { return radius_; }
  // True once the server said the newest view is complete (ViewReady); any thread.
  // A player whose connection closed has no view to wait for.
  bool view_ready() const {
    return gone_.load(std::memory_order_acquire) || ready_view_.load(std::memory_order_acquire) ==
                                                        views_sent_.load(std::memory_order_acquire);
  }

 private:
  struct PendingEdit {
    double sent_s;
    bool have_result = false;
    std::set<client::ChunkKey> waiting;  // changed chunks in view whose new mesh has not arrived
    wire::Envelope edit;                 // --reconnect: sent again when unanswered
  };

  void connect();
  void read_more();
  void on_message(const wire::Envelope& m);
  void on_chunk_mesh(const wire::ChunkMesh& m);
  std::optional<std::string> apply_mesh(const wire::ChunkMesh& m);
  void send(const wire::Envelope& m);
  void write_more();
  void tick();
  void walk(double dt);
  void send_view();
  void send_edit();
  void fail(const std::string& cause, bool disconnect);
  void reconnect();  // --reconnect: a new link to the next server
  bool in_view(const client::ChunkKey& k) const;
  void publish_position();

  LoadTest& test_;
  const int id_;
  std::mt19937 rng_;
  PlayerStrand strand_;
  std::unique_ptr<PlayerLink> link_;
  boost::asio::steady_timer timer_, retry_timer_;
  std::deque<std::vector<uint8_t>> outbox_;  // serialized Envelopes, the front one being written
  bool writing_ = false, welcomed_ = false, closed_ = false, ticking_ = false;
  // --reconnect: the server the link goes to (an index into host:port and more_servers),
  // the link's generation (callbacks of an older link are ignored), when the connection
  // was lost (-1: connected), and whether the first view after it is still incomplete.
  size_t server_ = 0;
  uint64_t link_gen_ = 0;
  double lost_s_ = -1;
  bool awaiting_view_ = false;

  float x_ = 0, y_ = 0, z_ = 0, heading_ = 0;
  std::array<std::atomic<float>, 3> published_{};  // x_, y_, z_ for other players
  client::ChunkKey view_chunk_{};
  std::array<float, 3> view_position_{};
  uint32_t radius_ = 0;
  double next_edit_s_ = 0, last_ping_s_ = 0, last_tick_s_ = 0;
  double view_sent_s_ = -1;
  bool first_view_done_ = false;
  std::atomic<uint64_t> views_sent_{0};  // the newest SetView's view_id
  std::atomic<uint64_t> ready_view_{0};  // view_id of the newest ViewReady
  std::atomic<bool> gone_{false};        // the connection closed
  uint64_t next_request_ = 1;
  std::map<uint64_t, PendingEdit> pending_;
  client::ChunkCache cache_;                          // level 0
  std::map<uint32_t, client::ChunkCache> lod_cache_;  // levels >= 1 (a LOD view)
};

}  // namespace vox::loadtest
