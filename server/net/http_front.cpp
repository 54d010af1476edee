#include "server/net/http_front.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/beast/http.hpp>
#include <optional>

#include "server/net/address_key.hpp"

namespace vox::net {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;

namespace {

// Requests one connection may make (keep-alive) before it is closed, and how long it may
// wait idle for the next: a connection is not held for long by keeping it alive.
constexpr int kMaxRequests = 32;
constexpr auto kKeepAliveIdle = std::chrono::seconds(2);
// After a failed accept (out of descriptors), the next waits this long.
constexpr auto kAcceptRetry = std::chrono::milliseconds(100);
// A response must be written within this (a file to a slow reader).
constexpr auto kWriteTimeout = std::chrono::seconds(30);

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool plain_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
         c == '-' || c == '_';
}

std::string_view content_type(std::string_view path) {
  const auto dot = path.rfind('.');
  const std::string_view ext = dot == std::string_view::npos ? "" : path.substr(dot + 1);
  if (ext == "html") return "text/html; charset=utf-8";
  if (ext == "js" || ext == "mjs") return "text/javascript; charset=utf-8";
  if (ext == "css") return "text/css; charset=utf-8";
  if (ext == "json" || ext == "map") return "application/json";
  if (ext == "png") return "image/png";
  if (ext == "svg") return "image/svg+xml";
  if (ext == "wasm") return "application/wasm";
  if (ext == "proto" || ext == "txt") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

// Served at / when the viewer was not built.
constexpr std::string_view kNoViewerPage =
    "<!doctype html><html><head><meta charset=\"utf-8\"><title>voxeld</title></head><body>"
    "<h1>voxeld</h1><p>This server speaks the voxeld protocol over WebSocket at "
    "<code>/ws</code>, but its viewer was not built: run <code>bash scripts/setup.sh</code> "
    "(it runs <code>npm ci</code> in <code>clients/web</code> and bundles the viewer), or "
    "start voxeld with <code>--http-root</code> naming the viewer's folder.</p></body></html>";

}  // namespace

std::string static_path(std::string_view target) {
  target = target.substr(0, target.find_first_of("?#"));
  if (target.empty() || target.front() != '/') return {};
  std::string path;
  for (size_t i = 1; i < target.size(); ++i) {
    char c = target[i];
    if (c == '%') {
      if (i + 2 >= target.size()) return {};
      const int hi = hex_value(target[i + 1]), lo = hex_value(target[i + 2]);
      if (hi < 0 || lo < 0) return {};
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    }
    if (c != '/' && !plain_char(c)) return {};
    path.push_back(c);
  }
  if (path.empty()) return "index.html";
  // Plain segments only: no "", ".", "..".
  size_t start = 0;
  for (;;) {
    const size_t end = path.find('/', start);
    const std::string_view segment =
        std::string_view(path).substr(start, end == std::string::npos ? end : end - start);
    if (segment.empty() || segment.front() == '.') return {};  // ., .., dotfiles
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return path;
}

bool origin_allowed(std::string_view origin, std::string_view host,
                    const std::vector<std::string>& allow_origins) {
  if (origin.empty()) return true;  // not a page: a program can send any Origin anyway
  for (const std::string& o : allow_origins) {
    if (o == "*" || o == origin) return true;
  }
  // The page's own origin: its scheme, then the host it asked for (a TLS proxy in front
  // keeps the Host header).
  for (std::string_view scheme : {"http://", "https://"}) {
    if (origin.size() == scheme.size() + host.size() && origin.starts_with(scheme) &&
        origin.substr(scheme.size()) == host && !host.empty())
      return true;
  }
  return false;
}

// One HTTP connection, on its own strand (the stream's executor): requests in turn, then
// either the end or an upgrade handed over.
class HttpFront::Conn : public std::enable_shared_from_this<Conn> {
 public:
  struct Shared {
    std::shared_ptr<const HttpConfig> config;
    ServerCounters& counters;
    std::shared_ptr<SharedLogRateLimit> logs;
    std::shared_ptr<AdmissionGate> gate;
    std::shared_ptr<const Upgraded> upgraded;
    std::shared_ptr<std::atomic<bool>> stopped;
  };

  // `proxy`: the peer is a trusted proxy.
  Conn(StrandSocket socket, std::string address, bool proxy, Shared shared)
      : stream_(std::move(socket)),
        address_(std::move(address)),
        proxy_(proxy),
        s_(std::move(shared)) {}
  ~Conn() { s_.gate->release(address_, false); }

  void start() { read_request(); }

 private:
  void read_request() {
    if (s_.stopped->load() || ++requests_ > kMaxRequests) return close();
    parser_.emplace();
    parser_->header_limit(static_cast<uint32_t>(s_.config->max_header_bytes));
    parser_->body_limit(0);
    stream_.expires_after(requests_ == 1 ? s_.config->request_timeout
                                         : std::min<std::chrono::milliseconds>(
                                               s_.config->request_timeout, kKeepAliveIdle));
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, size_t) { self->on_request(ec); });
  }

  void on_request(beast::error_code ec) {
    if (ec == http::error::end_of_stream || ec == asio::error::eof ||
        ec == asio::error::connection_reset)
      return close();
    if (ec == beast::error::timeout) {
      // An idle keep-alive connection is closed quietly; a request begun and not finished
      // in time is a slow one.
      if (parser_->got_some()) refused(HttpRefusedBy::kTimeout, "a request not complete in time");
      return close();
    }
    if (ec == http::error::header_limit) {
      return respond_error(http::status::request_header_fields_too_large,
                           HttpRefusedBy::kHeaderTooBig, "the request's header is too large");
    }
    if (ec) {
      return respond_error(http::status::bad_request, HttpRefusedBy::kBadRequest,
                           "a request that is not well-formed HTTP/1.1 without a body");
    }
    const auto& req = parser_->get();
    const std::string_view target(req.target().data(), req.target().size());
    const std::string_view route = target.substr(0, target.find('?'));
    if (route == "/ws") return upgrade();
    if (req.method() != http::verb::get && req.method() != http::verb::head)
      return respond_error(http::status::method_not_allowed, HttpRefusedBy::kBadMethod,
                           "only GET and HEAD are served", Header{http::field::allow, "GET, HEAD"});
    if (route == "/healthz") return health();
    const std::string path = static_path(target);
    if (path.empty())
      return respond_error(http::status::bad_request, HttpRefusedBy::kBadRequest,
                           "the path must name a file by plain segments");
    serve_file(path);
  }

  // A load balancer's health check (docs/CLUSTER.md, "Clients"): 200 while this server
  // should take players, 503 with the reason otherwise.
  void health() {
    const std::optional<std::string> why =
        s_.config->unhealthy ? s_.config->unhealthy() : std::nullopt;
    respond(why ? http::status::service_unavailable : http::status::ok, "text/plain; charset=utf-8",
            why ? *why + "\n" : "ok\n", true, Header{http::field::cache_control, "no-store"});
  }

  void upgrade() {
    const auto& req = parser_->get();
    if (!websocket::is_upgrade(req))
      return respond_error(http::status::upgrade_required, HttpRefusedBy::kBadRequest,
                           "/ws takes a WebSocket upgrade",
                           Header{http::field::upgrade, "websocket"});
    // The player's address: behind a trusted proxy, the client X-Forwarded-For names.
    std::string player = address_;
    std::string forwarded;
    if (proxy_) {
      const auto [first, last] = req.equal_range("X-Forwarded-For");
      for (auto field = first; field != last; ++field) {
        if (!forwarded.empty()) forwarded += ',';
        forwarded.append(field->value().data(), field->value().size());
      }
      if (!forwarded.empty()) {
        auto client = forwarded_client(forwarded, s_.config->trusted_proxies);
        if (!client)
          return respond_error(http::status::bad_request, HttpRefusedBy::kBadRequest,
                               "X-Forwarded-For from the proxy names no IP address");
        player = std::move(*client);
      }
    }
    // A proxied upgrade carries the public host name: on a loopback-bound server it must be
    // one the operator listed (DNS rebinding also works through a proxy).
    const auto origin = req[http::field::origin];
    const std::string_view host(req[http::field::host].data(), req[http::field::host].size());
    if (!origin_allowed({origin.data(), origin.size()}, host, s_.config->allow_origins) ||
        (!origin.empty() && !host_allowed(host, s_.config->bind) &&
         !(proxy_ && host_listed(host, s_.config->allow_origins)))) {
      return respond_error(http::status::forbidden, HttpRefusedBy::kOrigin,
                           "WebSocket connections from this origin are not allowed "
                           "(--http-allow-origin)");
    }
    stream_.expires_never();
    ws_.emplace(std::move(stream_));
    websocket::stream_base::timeout timeouts{};
    timeouts.handshake_timeout = s_.config->request_timeout;
    timeouts.idle_timeout = websocket::stream_base::none();
    timeouts.keep_alive_pings = false;
    ws_->set_option(timeouts);
    ws_->set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "voxeld"); }));
    ws_->async_accept(
        req, [self = shared_from_this(), player = std::move(player)](beast::error_code ec) mutable {
          if (ec) {  // the stream closes with this connection
            if (ec == beast::error::timeout) {
              self->refused(HttpRefusedBy::kTimeout, "a slow upgrade");
            } else {
              self->refused(HttpRefusedBy::kBadRequest, "a WebSocket handshake that is not valid");
            }
            return;
          }
          ServerCounters::bump(self->s_.counters.ws_upgrades);
          if (self->s_.stopped->load()) return;
          (*self->s_.upgraded)(std::move(*self->ws_), std::move(player));
          self->ws_.reset();
        });
  }

  void serve_file(const std::string& path) {
    const auto& req = parser_->get();
    const HttpConfig& config = *s_.config;
    http::response<http::file_body> res;
    bool found = false;
    if (!config.root.empty()) {
      const std::filesystem::path file = config.root / path;
      std::error_code fs_ec;
      // A link may not lead out of the root.
      const auto real = std::filesystem::canonical(file, fs_ec);
      const auto root = std::filesystem::canonical(config.root, fs_ec);
      const auto rel = real.lexically_relative(root);
      if (!fs_ec && !rel.empty() && *rel.begin() != ".." &&
          std::filesystem::is_regular_file(real, fs_ec) &&
          std::filesystem::file_size(file, fs_ec) <= config.max_file_bytes) {
        beast::error_code ec;
        res.body().open(real.c_str(), beast::file_mode::scan, ec);
        found = !ec;
      }
    }
    if (!found) {
      if (path == "index.html")
        return respond(http::status::ok, "text/html; charset=utf-8", std::string(kNoViewerPage));
      return respond_error(http::status::not_found, HttpRefusedBy::kNotFound, "no such file");
    }
    res.result(http::status::ok);
    res.version(req.version());
    res.set(http::field::server, "voxeld");
    const std::string_view type = content_type(path);
    res.set(http::field::content_type, beast::string_view(type.data(), type.size()));
    res.set(http::field::cache_control, "no-cache");
    res.set("X-Content-Type-Options", "nosniff");
    res.keep_alive(req.keep_alive());
    res.prepare_payload();
    const bool head = req.method() == http::verb::head;
    auto sp = std::make_shared<http::response<http::file_body>>(std::move(res));
    send(std::move(sp), head);
  }

  struct Header {
    http::field field;
    const char* value;
  };
  void respond(http::status status, std::string_view type, std::string body, bool keep = true,
               std::optional<Header> extra = {}) {
    const auto& req = parser_->get();
    auto res = std::make_shared<http::response<http::string_body>>(status, req.version());
    if (extra) res->set(extra->field, extra->value);
    res->set(http::field::server, "voxeld");
    res->set(http::field::content_type, beast::string_view(type.data(), type.size()));
    res->set("X-Content-Type-Options", "nosniff");
    res->keep_alive(keep && req.keep_alive());
    res->body() = std::move(body);
    res->prepare_payload();
    send(std::move(res), req.method() == http::verb::head);
  }

  void respond_error(http::status status, HttpRefusedBy why, std::string_view message,
                     std::optional<Header> extra = {}) {
    refused(why, message);
    // After a request that was not whole (or too large), the stream cannot be read on.
    const bool keep = why != HttpRefusedBy::kHeaderTooBig && why != HttpRefusedBy::kBadRequest;
    respond(status, "text/plain; charset=utf-8", std::string(message) + "\n", keep, extra);
  }

  template <class Response>
  void send(std::shared_ptr<Response> res, bool head) {
    ServerCounters::bump(s_.counters.http_requests);
    stream_.expires_after(kWriteTimeout);
    const bool keep = res->keep_alive();
    auto done = [self = shared_from_this(), res, keep](beast::error_code ec, size_t) {
      if (ec || !keep) return self->close();
      self->read_request();
    };
    if (head) {  // the same header, without its body
      auto sr = std::make_shared<http::response_serializer<typename Response::body_type>>(*res);
      http::async_write_header(
          stream_, *sr,
          [sr, done = std::move(done)](beast::error_code ec, size_t n) mutable { done(ec, n); });
      return;
    }
    http::async_write(stream_, *res, std::move(done));
  }

  void refused(HttpRefusedBy why, std::string_view message) {
    ServerCounters::bump(s_.counters.http_refused[static_cast<size_t>(why)]);
    if (auto suppressed = s_.logs->allow("http_refused")) {
      spdlog::info("http: refused ({}) from {}: {}{}", to_string(why), address_, message,
                   *suppressed ? fmt::format(" [{} more since the last such line]", *suppressed)
                               : std::string());
    }
  }

  void close() {
    beast::error_code ignored;
    stream_.socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    stream_.close();
  }

  WsStream::next_layer_type stream_;
  std::optional<WsStream> ws_;
  const std::string address_;  // the peer's key: the gate's
  const bool proxy_;
  Shared s_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::empty_body>> parser_;
  int requests_ = 0;
};

void HttpFront::set_max_per_address(size_t cap) {
  AdmissionLimits limits = gate_->limits();
  limits.max_per_address = limits.max_handshaking_per_address = cap;
  gate_->set_limits(limits);
}

HttpFront::HttpFront(asio::io_context& io, HttpConfig config, ServerCounters& counters,
                     std::shared_ptr<SharedLogRateLimit> logs, Upgraded upgraded)
    : io_(io),
      strand_(asio::make_strand(io)),
      config_(std::make_shared<const HttpConfig>(std::move(config))),
      counters_(counters),
      logs_(std::move(logs)),
      gate_(std::make_shared<AdmissionGate>(AdmissionLimits{
          .max_players = 0,
          .max_handshaking = config_->max_connections ? config_->max_connections : SIZE_MAX,
          .max_per_address = config_->max_per_address,
          .max_handshaking_per_address = config_->max_per_address})),
      upgraded_(std::make_shared<const Upgraded>(std::move(upgraded))),
      acceptor_(strand_),
      retry_timer_(strand_),
      stopped_(std::make_shared<std::atomic<bool>>(false)) {}

HttpFront::~HttpFront() { stopped_->store(true); }

void HttpFront::start() {
  const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(config_->bind), config_->port);
  acceptor_.open(endpoint.protocol());
  acceptor_.set_option(asio::ip::tcp::acceptor::reuse_address(true));
  acceptor_.bind(endpoint);
  acceptor_.listen();
  port_ = acceptor_.local_endpoint().port();
  spdlog::info("voxeld serving HTTP and WebSocket (/ws) on {}:{} ({})", config_->bind, port_,
               config_->root.empty() ? std::string("no viewer files")
                                     : "files from " + config_->root.string());
  accept();
}

void HttpFront::stop() {
  stopped_->store(true);
  asio::post(strand_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    retry_timer_.cancel();
  });
}

void HttpFront::accept() {
  acceptor_.async_accept(
      Strand(io_.get_executor()), [this](boost::system::error_code ec, StrandSocket socket) {
        if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;
        if (!ec) {
          boost::system::error_code peer_ec;
          const auto peer = socket.remote_endpoint(peer_ec);
          if (!peer_ec) {
            std::string address = address_key(peer.address());
            const auto& proxies = config_->trusted_proxies;
            const bool proxy = std::find(proxies.begin(), proxies.end(),
                                         address_text(peer.address())) != proxies.end();
            if (const auto verdict = gate_->connect(address, !proxy);
                verdict != AdmissionControl::Verdict::kAdmit) {
              busy(std::move(socket), address, verdict == AdmissionControl::Verdict::kAddressFull);
            } else {
              socket.set_option(asio::ip::tcp::no_delay(true), peer_ec);
              std::make_shared<Conn>(
                  std::move(socket), std::move(address), proxy,
                  Conn::Shared{config_, counters_, logs_, gate_, upgraded_, stopped_})
                  ->start();
            }
          }
        } else if (out_of_resources(ec)) {
          // Out of descriptors and the like: log (rate-limited) and try again a little later
          // (at once, the loop would spin while the condition lasts).
          if (auto suppressed = logs_->allow("http_accept"))
            spdlog::warn("http accept failed: {} [{} more]", ec.message(), *suppressed);
          retry_timer_.expires_after(kAcceptRetry);
          retry_timer_.async_wait([this](boost::system::error_code e) {
            if (!e) accept();
          });
          return;
        }
        accept();
      });
}

// Over the caps: a 503 written without waiting (a full socket buffer just loses it).
void HttpFront::busy(StrandSocket socket, const std::string& address, bool address_full) {
  ServerCounters::bump(counters_.http_refused[static_cast<size_t>(HttpRefusedBy::kBusy)]);
  const std::string_view why = address_full ? "too many connections from your address\n"
                                            : "too many connections to this server\n";
  const std::string response = fmt::format(
      "HTTP/1.1 503 Service Unavailable\r\nServer: voxeld\r\nContent-Type: text/plain\r\n"
      "Content-Length: {}\r\nRetry-After: 5\r\nConnection: close\r\n\r\n{}",
      why.size(), why);
  boost::system::error_code ec;
  socket.non_blocking(true, ec);
  socket.write_some(asio::buffer(response), ec);
  socket.close(ec);
  if (auto suppressed = logs_->allow("http_busy")) {
    spdlog::warn("http: refusing a connection from {}: {} [{} more]", address,
                 why.substr(0, why.size() - 1), *suppressed);
  }
}

const char* to_string(HttpRefusedBy why) {
  switch (why) {
    case HttpRefusedBy::kBadRequest:
      return "bad request";
    case HttpRefusedBy::kNotFound:
      return "not found";
    case HttpRefusedBy::kBadMethod:
      return "method not allowed";
    case HttpRefusedBy::kHeaderTooBig:
      return "header too large";
    case HttpRefusedBy::kOrigin:
      return "origin not allowed";
    case HttpRefusedBy::kBusy:
      return "busy";
    case HttpRefusedBy::kTimeout:
      return "timeout";
    case HttpRefusedBy::kCount:
      break;
  }
  return "?";
}

bool host_allowed(std::string_view host, std::string_view bind) {
  const auto loopback = [](std::string_view name) {
    return name == "localhost" || name.starts_with("127.") || name == "[::1]" || name == "::1";
  };
  if (!loopback(bind)) return true;  // a public server: any name may lead to it
  // A loopback server answers upgrades only to a loopback name, so that a page whose name
  // an attacker points at 127.0.0.1 (DNS rebinding) cannot open it.
  std::string_view name = host;
  if (name.starts_with("[")) {
    name = name.substr(0, name.find(']') + 1);
  } else if (const size_t colon = name.rfind(':'); colon != std::string_view::npos) {
    name = name.substr(0, colon);
  }
  return loopback(name);
}

bool host_listed(std::string_view host, const std::vector<std::string>& allow_origins) {
  for (std::string_view origin : allow_origins) {
    for (std::string_view scheme : {"http://", "https://"}) {
      if (origin.starts_with(scheme) && origin.substr(scheme.size()) == host && !host.empty())
        return true;
    }
  }
  return false;
}

std::optional<std::string> forwarded_client(std::string_view forwarded_for,
                                            const std::vector<std::string>& trusted_proxies) {
  std::optional<std::string> client;
  while (!forwarded_for.empty()) {
    const size_t comma = forwarded_for.rfind(',');
    std::string_view entry =
        comma == std::string_view::npos ? forwarded_for : forwarded_for.substr(comma + 1);
    forwarded_for = forwarded_for.substr(0, comma == std::string_view::npos ? 0 : comma);
    while (!entry.empty() && (entry.front() == ' ' || entry.front() == '\t'))
      entry.remove_prefix(1);
    while (!entry.empty() && (entry.back() == ' ' || entry.back() == '\t')) entry.remove_suffix(1);
    if (entry.size() > 2 && entry.front() == '[' && entry.back() == ']')
      entry = entry.substr(1, entry.size() - 2);
    boost::system::error_code ec;
    const auto address = asio::ip::make_address(std::string(entry), ec);
    if (ec) return std::nullopt;
    client = address_key(address);
    if (std::find(trusted_proxies.begin(), trusted_proxies.end(), address_text(address)) ==
        trusted_proxies.end())
      return client;
  }
  return client;
}

}  // namespace vox::net
