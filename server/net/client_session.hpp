// One connected player. Each session runs on its own strand: a read chain (length, body,
// dispatch) and a write chain that always sends the newest version of the nearest stale
// chunk, as a delta from what the client holds. Other threads only post to the strand.
#pragma once

#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <vector>

#include "net/asio.hpp"
#include "net/send_scheduler.hpp"
#include "net/server_counters.hpp"
#include "pipeline/world_pipeline.hpp"
#include "proto/framing.hpp"
#include "voxel.pb.h"

namespace vox::net {

namespace asio = boost::asio;

struct ServerConfig {
  std::string bind = "127.0.0.1";
  uint16_t port = 7777;
  size_t max_clients = 256;
  uint32_t max_view_radius = 12;            // chunks
  size_t max_frame_bytes = 64 * 1024;       // largest client frame accepted
  size_t max_bytes_in_flight = 256 * 1024;  // per session, in one write
  // Queued results/errors before a client counts as not reading.
  size_t max_control_bytes = 1 << 20;
  size_t max_edits_in_flight = 256;  // a client's edits queued in the pipeline at once
  std::chrono::milliseconds handshake_timeout{5000};
  std::chrono::milliseconds idle_timeout{60000};   // nothing received for this long: disconnect
  std::chrono::milliseconds write_timeout{10000};  // a write not finished in this time: disconnect
  std::string server_version = "voxeld 0.1.0";
};

class ClientSession : public std::enable_shared_from_this<ClientSession> {
 public:
  ClientSession(asio::ip::tcp::socket socket, uint64_t id, const ServerConfig& config,
                pipeline::WorldPipeline& pipeline, ServerCounters& counters);
  ~ClientSession();

  void start();  // any thread, once
  void on_chunks_published(
      std::shared_ptr<const std::vector<world::ChunkCoord>> chunks);  // any thread
  // Any thread: false when none of `chunks` can be in this session's view, so the publish
  // fan-out skips it (the scheduler still decides what is really sent). The view is
  // updated before the session first looks its chunks up in the store, so a mesh
  // published meanwhile is either seen by that lookup or passes this filter.
  bool may_see(const std::vector<world::ChunkCoord>& chunks) const;
  // Sends an Error and closes (SHUTTING_DOWN, SERVER_FULL); any thread.
  void close_with_error(wire::Error::Code code, std::string message);
  uint64_t id() const { return id_; }
  bool is_player() const { return player_.load(std::memory_order_relaxed); }

 private:
  // All strand only.
  void read_more();
  void on_frame(const std::vector<uint8_t>& body);
  void handle_hello(const wire::Hello& hello);
  void handle_set_view(const wire::SetView& view);
  void handle_edit(const wire::Edit& edit);
  void send_error(wire::Error::Code code, const std::string& message, bool close);
  void queue_control(const wire::Envelope& message);
  void pump();
  bool append_next_mesh(std::vector<uint8_t>& out);
  void arm_idle_timer();
  void shutdown();

  asio::ip::tcp::socket socket_;
  asio::strand<asio::any_io_executor> strand_;
  asio::steady_timer handshake_timer_, idle_timer_, write_timer_;
  const uint64_t id_;
  const ServerConfig& config_;
  pipeline::WorldPipeline& pipeline_;
  ServerCounters& counters_;
  std::atomic<bool> player_{false};

  proto::FrameDecoder decoder_;
  std::array<uint8_t, 16 * 1024> read_buffer_;
  std::string name_;
  bool closing_ = false;
  bool writing_ = false;
  size_t edits_in_flight_ = 0;  // submitted, result not yet queued

  SendScheduler scheduler_;
  mutable std::mutex view_mutex_;  // guards the two below (also read by the fan-out)
  world::ChunkCoord view_center_{};
  int view_radius_ = -1;
  std::deque<std::vector<uint8_t>> control_;  // framed messages sent before meshes
  size_t control_bytes_ = 0;
  std::vector<uint8_t> write_buffer_;
  wire::Envelope mesh_message_;  // reused by append_next_mesh
};

}  // namespace vox::net
