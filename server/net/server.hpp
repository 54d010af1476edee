// The network front end: accepts TCP connections, and WebSocket ones through the HTTP
// port (HttpFront), keeps the session registry, forwards the pipeline's publications to
// the sessions, logs a stats line, and shuts down cleanly.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "server/net/admission_control.hpp"
#include "server/net/asio.hpp"
#include "server/net/client_session.hpp"
#include "server/net/http_front.hpp"
#include "server/net/log_hygiene.hpp"
#include "server/net/publish_coalescer.hpp"
#include "server/net/server_counters.hpp"

namespace vox::net {

class Server {
 public:
  // `counters` outlive the server (the pipeline's observer writes to them too).
  Server(asio::io_context& io, ServerConfig config, pipeline::WorldPipeline& pipeline,
         ServerCounters& counters);
  ~Server();

  // Binds and starts accepting; throws boost::system::system_error when it cannot bind.
  // Before the io_context runs (or on strand_).
  void start();
  uint16_t port() const { return port_; }  // the bound port (after start)
  // The HTTP port (after start; 0: none: off, or its default port was taken).
  uint16_t http_port() const { return http_ ? http_->port() : 0; }
  // Stops accepting and tells every client SHUTTING_DOWN; sessions close themselves.
  void stop();                   // any thread
  size_t session_count() const;  // any thread
  const ServerCounters& counters() const { return counters_; }
  void start_stats_log(std::chrono::seconds interval);  // before the io_context runs
  // The world's bans (voxeld's, read from its store); before start. Without: bans in
  // memory only. Stopped by ~Server (its callbacks post to the sessions' strands).
  void set_bans(std::shared_ptr<BanKeeper> bans) { bans_ = std::move(bans); }
  // A reload (SIGHUP): the token key and budgets for the next Hellos, the connection caps
  // for the next connections. Any thread.
  void reload(const LiveValues& live, const AdmissionLimits& caps);

 private:
  // All strand_ only.
  void accept();
  void admit(StrandSocket socket);
  // A connection from a trusted proxy: its PROXY header, then admitted as its client.
  void read_proxy_header(StrandSocket socket, boost::asio::ip::address proxy);
  void admit_as(StrandSocket socket, const std::string& address);
  void refuse(StrandSocket socket, AdmissionControl::Verdict why);
  // A WebSocket connection's strand (not strand_): admitted like a TCP one.
  void admit_websocket(WsStream ws, std::string address);
  void start_http();
  // Connection or session members (any strand).
  void add_session(const std::shared_ptr<ClientSession>& session);
  std::string refusal(AdmissionControl::Verdict why);    // counts it; the Error's bytes
  void fan_out(std::vector<world::ChunkCoord> changed);  // any thread
  void fan_out_gathered();                               // strand_
  void housekeeping();  // every second: the sessions' memory into the pipeline's budget
  void log_stats();
  void arm_stats_timer();

  asio::io_context& io_;
  // The acceptor, the timers and their handlers live on this strand, so stop() from a
  // signal handler is safe with several --io-threads.
  asio::strand<asio::io_context::executor_type> strand_;
  std::shared_ptr<const ServerConfig> shared_config_;  // shared with the sessions
  const ServerConfig& config_;                         // *shared_config_
  pipeline::WorldPipeline& pipeline_;
  asio::ip::tcp::acceptor acceptor_;
  asio::steady_timer stats_timer_, housekeeping_timer_;
  asio::steady_timer accept_retry_timer_;  // the next accept after a failed one
  std::chrono::seconds stats_interval_{10};
  uint16_t port_ = 0;
  ServerCounters& counters_;
  std::shared_ptr<AdmissionGate> admission_;  // shared with the sessions
  std::shared_ptr<SharedLogRateLimit> logs_;
  std::shared_ptr<PlayerRegistry<ClientSession>> players_;
  uint64_t subscription_ = 0;
  uint64_t lod_subscription_ = 0;
  std::atomic<uint64_t> next_session_{1};
  std::atomic<size_t> proxy_reads_{0};  // connections from proxies still sending their header
  std::unique_ptr<HttpFront> http_;

  // Publications gathered while a fan-out is unhandled (publish_coalescer.hpp); shared
  // with the fan-outs' lists, whose deleters may run after the Server is gone.
  struct PublishGate {
    std::mutex mutex;  // leaf lock
    PublishCoalescer rules;
    bool stopped = false;  // the Server is gone
  };
  std::shared_ptr<PublishGate> publish_;

  std::shared_ptr<SessionDirectory<ClientSession>> sessions_;  // shared with the sessions
  std::shared_ptr<BanKeeper> bans_;                            // shared with the sessions
  std::shared_ptr<LiveSettings> live_;  // shared with the sessions: what a reload changes

  struct Snapshot {
    uint64_t edits = 0, meshes = 0, bytes = 0;
    std::chrono::steady_clock::time_point at;
  } last_stats_;
};

}  // namespace vox::net
