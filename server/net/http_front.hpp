// voxeld's HTTP port (--http-port): the viewer's static files, and the WebSocket upgrade
// at /ws that makes a connection a session's transport (ws_connection.hpp). Every input is
// checked at the edge:
// - a request must be whole within `request_timeout` (a slow one, slowloris, is closed),
//   its header within `max_header_bytes` (431), with no body (400);
// - GET and HEAD only (405); a path is percent-decoded and must name a file under the
//   static root by plain segments (`..`, `.`, `\`, NUL or an empty segment: 400), else 404;
// - an upgrade is taken at /ws only (elsewhere 404; a plain request there: 426), and only
//   from the page's own origin or one of `allow_origins` ("*": any), and on a loopback
//   server only to a loopback host name (DNS rebinding); no Origin header (a program, not
//   a page) is let in (403 otherwise);
// - behind a trusted proxy (`trusted_proxies`), the player is the client X-Forwarded-For
//   names (an entry that is not an address: 400), and the proxy has no per-address cap; a
//   proxied upgrade to a loopback-bound server must name a loopback host or the host of
//   an allowed origin (the public name);
// - a path names no dotfile, and a link under the root may not lead out of it;
// - a keep-alive connection waits at most kKeepAliveIdle for its next request (closed
//   quietly), and makes at most kMaxRequests;
// - connections are capped in total and per address (503).
// Each refusal is counted (ServerCounters::http_refused) and, rate-limited, logged.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "server/net/admission_control.hpp"
#include "server/net/asio.hpp"
#include "server/net/http_config.hpp"
#include "server/net/log_hygiene.hpp"
#include "server/net/server_counters.hpp"
#include "server/net/ws_connection.hpp"

namespace vox::net {

// Whether `target` (a request's path, with its query) names a file under the static root:
// its relative path ("index.html" for "/"), or empty when it leaves the root or is not
// plain (see above). Pure; tested alone.
std::string static_path(std::string_view target);

// Whether an upgrade with this Origin header (empty: none) to `host` (the Host header) is
// allowed. Pure.
bool origin_allowed(std::string_view origin, std::string_view host,
                    const std::vector<std::string>& allow_origins);

// Whether an upgrade's Host (with its port) may reach a server bound to `bind`: any, unless
// it is bound to loopback; then only a loopback name (DNS rebinding). Pure.
bool host_allowed(std::string_view host, std::string_view bind);

// Whether `host` (a Host header) is the host of one of `allow_origins` ("*" names none).
// Pure.
bool host_listed(std::string_view host, const std::vector<std::string>& allow_origins);

// The client a trusted proxy's X-Forwarded-For names (the values of every such header,
// joined by commas): the address key of the rightmost entry that is not itself a trusted
// proxy (each proxy appends the address it accepted from), or of the leftmost when all are.
// None when an entry is not an IP address or there is none. Pure.
std::optional<std::string> forwarded_client(std::string_view forwarded_for,
                                            const std::vector<std::string>& trusted_proxies);

const char* to_string(HttpRefusedBy why);

class HttpFront {
 public:
  // A WebSocket connection accepted: its stream (handshake done) and the peer's address
  // key. Runs on the connection's strand.
  using Upgraded = std::function<void(WsStream ws, std::string address)>;

  // `counters` and `logs` outlive the front; `upgraded` is called until stop().
  HttpFront(boost::asio::io_context& io, HttpConfig config, ServerCounters& counters,
            std::shared_ptr<SharedLogRateLimit> logs, Upgraded upgraded);
  ~HttpFront();

  // Binds and starts accepting; throws boost::system::system_error when it cannot bind.
  // Before the io_context runs.
  void start();
  uint16_t port() const { return port_; }
  // Stops accepting; open HTTP connections end at their next request. Any thread.
  void stop();
  // A reload's new cap on connections per address (http_per_address_cap); any thread.
  void set_max_per_address(size_t cap);

 private:
  class Conn;
  void accept();  // strand_ only
  void busy(StrandSocket socket, const std::string& address, bool address_full);

  boost::asio::io_context& io_;
  boost::asio::strand<boost::asio::io_context::executor_type> strand_;
  const std::shared_ptr<const HttpConfig> config_;
  ServerCounters& counters_;
  std::shared_ptr<SharedLogRateLimit> logs_;
  std::shared_ptr<AdmissionGate> gate_;  // HTTP connections by address
  std::shared_ptr<const Upgraded> upgraded_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer retry_timer_;  // the next accept after a failed one
  uint16_t port_ = 0;
  std::shared_ptr<std::atomic<bool>> stopped_;  // shared with the connections
};

}  // namespace vox::net
