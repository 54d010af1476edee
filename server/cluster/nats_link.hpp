// The cluster's messaging (docs/CLUSTER.md): one connection to NATS through its C client
// (libnats), reconnecting by itself. Subjects carry requests to a zone's owner and the
// facts it publishes after commit; PostgreSQL stays the truth, so a message lost while
// disconnected costs latency (receivers fill gaps from the zone logs), never correctness.
//
// Credentials come from the caller's configuration (a user and password), never from a
// command line. A failure to connect or a refused login throws ClusterError with one
// line naming the server; once connected, publishes while disconnected are buffered by
// the library (up to its reconnect buffer) and requests fail fast.
//
// Threads: any thread may publish, request, subscribe and unsubscribe. A subscription's
// handler runs on the library's delivery thread for that subscription, one message at a
// time, in order; it must not block long. Destroying the link (or unsubscribing) waits
// for a handler in progress; call neither from a handler.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace vox::cluster {

struct ClusterError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct NatsConfig {
  std::string url;  // nats://host:port
  std::string user, password;
  std::string name;  // the connection's name, as the server's monitoring shows it
  std::chrono::milliseconds connect_timeout{2000};
};

struct NatsMessage {
  std::string subject;
  std::string reply;              // where a request wants its answer; empty for a plain publish
  std::span<const uint8_t> data;  // valid during the handler only
  // On a reply subject: the server's word that nobody listened on the request's subject.
  bool no_responders = false;
};

class NatsLink {
 public:
  using Handler = std::function<void(const NatsMessage&)>;

  explicit NatsLink(const NatsConfig& config);
  ~NatsLink();
  NatsLink(const NatsLink&) = delete;
  NatsLink& operator=(const NatsLink&) = delete;

  // `reply`: a subject for the receiver's answer (empty: none).
  void publish(const std::string& subject, std::span<const uint8_t> data,
               const std::string& reply = {});
  // Sends a request and waits for the first answer: nullopt when none came within
  // `timeout`; ClusterError when nobody listens on the subject (no responders) or the
  // link is down.
  std::optional<std::vector<uint8_t>> request(const std::string& subject,
                                              std::span<const uint8_t> data,
                                              std::chrono::milliseconds timeout);
  // Handler for every message on `subject` (wildcards allowed); returns its id.
  uint64_t subscribe(const std::string& subject, Handler handler);
  void unsubscribe(uint64_t id);
  // Waits until the server has every message published so far (false: not in time).
  bool flush(std::chrono::milliseconds timeout);

  bool connected() const;
  uint64_t reconnects() const { return reconnects_.load(std::memory_order_relaxed); }
  const std::string& server() const { return server_; }  // the URL, for messages

 private:
  struct Subscription;
  struct Connection;
  std::string server_;
  std::unique_ptr<Connection> conn_;
  std::mutex mutex_;  // guards subscriptions_ (never held while a handler runs)
  std::map<uint64_t, std::unique_ptr<Subscription>> subscriptions_;
  uint64_t next_id_ = 1;
  std::atomic<uint64_t> reconnects_{0};
};

}  // namespace vox::cluster
