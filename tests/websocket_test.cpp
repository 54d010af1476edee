// voxeld's HTTP port against a real voxeld (server/net/http_front.hpp, ws_connection.hpp):
// the same session over WebSocket as over TCP, and every kind of bad input refused with a
// clear status or close code, counted in /metrics, while other players go on.
#include <gtest/gtest.h>

#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <map>
#include <sstream>

#include "server/net/http_front.hpp"
#include "tests/server_process.hpp"
#include "tests/session_test_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::test {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using Ws = websocket::stream<beast::tcp_stream>;

// Runs the io_context until `done` or the deadline (times kSlow); false on the deadline.
bool run_until(asio::io_context& io, const bool& done, std::chrono::milliseconds limit = 10s) {
  io.restart();
  const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
  while (!done && std::chrono::steady_clock::now() < deadline)
    io.run_for(std::chrono::milliseconds(20));
  return done;
}

// A WebSocket client of /ws, every wait bounded.
struct WsClient {
  // `forwarded_for`: an X-Forwarded-For header, as a proxy in front adds it; `host`: the
  // Host header, when not 127.0.0.1:port.
  explicit WsClient(uint16_t port, std::string origin = {}, std::string forwarded_for = {},
                    std::string host = {})
      : ws(io) {
    beast::get_lowest_layer(ws).connect({asio::ip::make_address("127.0.0.1"), port});
    ws.set_option(websocket::stream_base::decorator([=](websocket::request_type& req) {
      if (!origin.empty()) req.set(beast::http::field::origin, origin);
      if (!forwarded_for.empty()) req.set("X-Forwarded-For", forwarded_for);
      if (!host.empty()) req.set(beast::http::field::host, host);
    }));
    bool done = false;
    ws.async_handshake("127.0.0.1:" + std::to_string(port), "/ws",
                       [&](beast::error_code e) { handshake_error = e, done = true; });
    run_until(io, done);
    ws.binary(true);
  }
  void send(const wire::Envelope& m) { send_bytes(m.SerializeAsString()); }
  void send_bytes(const std::string& bytes) {
    bool done = false;
    ws.async_write(asio::buffer(bytes), [&](beast::error_code, size_t) { done = true; });
    run_until(io, done);
  }
  // The next message; none when the connection closed (close_code says how) or in time.
  std::optional<wire::Envelope> receive(std::chrono::milliseconds limit = 10s) {
    beast::flat_buffer buffer;
    bool done = false;
    beast::error_code ec;
    ws.async_read(buffer, [&](beast::error_code e, size_t) { ec = e, done = true; });
    if (!run_until(io, done, limit)) {
      beast::get_lowest_layer(ws).cancel();
      run_until(io, done);
      return std::nullopt;
    }
    if (ec) {
      closed = true;
      close_code = ws.reason().code;
      return std::nullopt;
    }
    wire::Envelope m;
    const auto data = buffer.cdata();
    EXPECT_TRUE(m.ParseFromArray(data.data(), static_cast<int>(data.size())));
    return m;
  }
  template <class Pred>
  std::optional<wire::Envelope> wait_for(Pred pred, std::chrono::milliseconds limit = 20s) {
    const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
    while (std::chrono::steady_clock::now() < deadline) {
      auto m = receive(std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now()));
      if (!m) return std::nullopt;
      if (pred(*m)) return m;
    }
    return std::nullopt;
  }
  // Reads until the server closes; its close code (0: not closed in time).
  uint16_t until_closed(std::chrono::milliseconds limit = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
    while (!closed && std::chrono::steady_clock::now() < deadline) receive(limit);
    return closed ? close_code : 0;
  }

  asio::io_context io;
  Ws ws;
  beast::error_code handshake_error;
  bool closed = false;
  uint16_t close_code = 0;
};

wire::Envelope explosion(uint64_t request, float x, float y, float z) {
  wire::Envelope m;
  m.mutable_edit()->set_request_id(request);
  auto* e = m.mutable_edit()->mutable_explosion();
  e->mutable_center()->set_x(x);
  e->mutable_center()->set_y(y);
  e->mutable_center()->set_z(z);
  e->set_radius(5);
  e->set_power(2);
  return m;
}

// One raw HTTP exchange: `request` written (a part at a time when `parts` > 1), the
// response until the server closes or the deadline.
std::string http_exchange(uint16_t port, const std::string& request,
                          std::chrono::milliseconds limit = 10s) {
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port});
  asio::write(s, asio::buffer(request));
  std::string response;
  std::array<char, 4096> buf;
  bool done = false;
  std::function<void()> read = [&] {
    s.async_read_some(asio::buffer(buf), [&](boost::system::error_code ec, size_t n) {
      response.append(buf.data(), n);
      if (ec) {
        done = true;
        return;
      }
      read();
    });
  };
  read();
  run_until(io, done, limit);
  return response;
}

std::map<std::string, double> metrics(uint16_t port) {
  const std::string response =
      http_exchange(port, "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n");
  std::map<std::string, double> out;
  std::istringstream lines(response.substr(response.find("\r\n\r\n") + 4));
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.rfind(' ');
    if (space != std::string::npos) out[line.substr(0, space)] = std::stod(line.substr(space + 1));
  }
  return out;
}

TEST(HttpRules, APathNamesAFileByPlainSegmentsOnly) {
  EXPECT_EQ(net::static_path("/"), "index.html");
  EXPECT_EQ(net::static_path("/?x=1"), "index.html");
  EXPECT_EQ(net::static_path("/viewer.js"), "viewer.js");
  EXPECT_EQ(net::static_path("/assets/a-b_c.1.js#top"), "assets/a-b_c.1.js");
  EXPECT_EQ(net::static_path("/%76iewer.js"), "viewer.js");
  for (const char* bad : {"",
                          "viewer.js",
                          "/../etc/passwd",
                          "/a/../../b",
                          "/%2e%2e/etc/passwd",
                          "/%2E%2E%2Fetc",
                          "/a//b",
                          "/./a",
                          "/a/.",
                          "/a\\b",
                          "/a%5c..%5cb",
                          "/a%00b",
                          "/%",
                          "/%4",
                          "/%zz",
                          "/a b",
                          "/a/",
                          "/..%2f..%2fetc",
                          "/.env",
                          "/.git/config",
                          "/assets/.hidden"}) {
    EXPECT_EQ(net::static_path(bad), "") << bad;
  }
}

TEST(HttpRules, AnUpgradeIsAllowedFromItsOwnOriginAListedOneOrAProgram) {
  const std::vector<std::string> none, listed = {"https://game.example"}, any = {"*"};
  EXPECT_TRUE(net::origin_allowed("", "127.0.0.1:7780", none));  // not a page
  EXPECT_TRUE(net::origin_allowed("http://127.0.0.1:7780", "127.0.0.1:7780", none));
  EXPECT_TRUE(net::origin_allowed("https://play.example", "play.example", none));  // TLS proxy
  EXPECT_FALSE(net::origin_allowed("http://evil.example", "127.0.0.1:7780", none));
  EXPECT_FALSE(net::origin_allowed("http://127.0.0.1:7781", "127.0.0.1:7780", none));
  EXPECT_FALSE(net::origin_allowed("http://127.0.0.1:7780", "", none));
  EXPECT_TRUE(net::origin_allowed("https://game.example", "127.0.0.1:7780", listed));
  EXPECT_FALSE(net::origin_allowed("https://game.example.evil", "127.0.0.1:7780", listed));
  EXPECT_TRUE(net::origin_allowed("http://anything", "x", any));
}

TEST(HttpRules, ALoopbackServerTakesUpgradesOnlyToALoopbackNameAgainstDnsRebinding) {
  EXPECT_TRUE(net::host_allowed("127.0.0.1:7780", "127.0.0.1"));
  EXPECT_TRUE(net::host_allowed("localhost:7780", "127.0.0.1"));
  EXPECT_TRUE(net::host_allowed("[::1]:7780", "::1"));
  EXPECT_TRUE(net::host_allowed("127.0.0.2", "127.0.0.1"));
  EXPECT_FALSE(net::host_allowed("evil.example:7780", "127.0.0.1"));
  EXPECT_FALSE(net::host_allowed("localhost.evil.example", "127.0.0.1"));
  EXPECT_TRUE(net::host_allowed("game.example", "0.0.0.0"));  // a public server
}

TEST(HttpRules, TheForwardedClientIsTheRightmostEntryThatIsNotATrustedProxy) {
  const std::vector<std::string> trusted = {"127.0.0.1", "10.0.0.2"};
  EXPECT_EQ(net::forwarded_client("203.0.113.7", trusted), "203.0.113.7");
  // A client may send its own header: the proxy appends, so only the rightmost is believed.
  EXPECT_EQ(net::forwarded_client("1.2.3.4, 203.0.113.7", trusted), "203.0.113.7");
  EXPECT_EQ(net::forwarded_client("198.51.100.1,203.0.113.7, 10.0.0.2", trusted), "203.0.113.7");
  EXPECT_EQ(net::forwarded_client("2001:db8::1", trusted), "2001:db8::/64");
  EXPECT_EQ(net::forwarded_client("[2001:db8::1]", trusted), "2001:db8::/64");
  EXPECT_EQ(net::forwarded_client("::ffff:203.0.113.7", trusted), "203.0.113.7");
  EXPECT_EQ(net::forwarded_client("127.0.0.1", trusted), "127.0.0.1");  // all trusted
  // A trusted proxy is one address, not its /64: a neighbour's entry is a client.
  const std::vector<std::string> v6 = {"2001:db8::10"};
  EXPECT_EQ(net::forwarded_client("203.0.113.7, 2001:db8::11", v6), "2001:db8::/64");
  EXPECT_EQ(net::forwarded_client("203.0.113.7, 2001:db8::10", v6), "203.0.113.7");
  for (const char* bad : {"", " ", "unknown", "203.0.113.7, nope", "203.0.113.7:4000", "1.2.3.4,,"})
    EXPECT_EQ(net::forwarded_client(bad, trusted), std::nullopt) << bad;
}

TEST(HttpRules, AProxiedHostMustBeTheHostOfAnAllowedOrigin) {
  const std::vector<std::string> allowed = {"https://play.example", "http://lan.example:8080"};
  EXPECT_TRUE(net::host_listed("play.example", allowed));
  EXPECT_TRUE(net::host_listed("lan.example:8080", allowed));
  EXPECT_FALSE(net::host_listed("evil.example", allowed));
  EXPECT_FALSE(net::host_listed("play.example.evil", allowed));
  EXPECT_FALSE(net::host_listed("", allowed));
  EXPECT_FALSE(net::host_listed("play.example", {"*"}));
}

TEST(WebSocket, APlayerJoinsGetsItsViewAndEditsAsOverTcp) {
  ServerProcess server({"--http-port", "auto", "--in-memory", "--metrics-port", "0"});
  WsClient ws(server.http_port());
  ASSERT_FALSE(ws.handshake_error) << ws.handshake_error.message();
  ws.send(client::make_hello("browser"));
  auto welcome = ws.wait_for([](const wire::Envelope& m) { return m.has_welcome(); });
  ASSERT_TRUE(welcome);
  EXPECT_EQ(welcome->welcome().protocol_version(), 1u);
  const float y = surface_y(16, 16);
  ws.send(client::make_set_view(16, y, 16, 1, 7));
  size_t meshes = 0;
  auto ready = ws.wait_for([&](const wire::Envelope& m) {
    meshes += m.has_chunk_mesh() ? 1 : 0;
    return m.has_view_ready();
  });
  ASSERT_TRUE(ready);
  EXPECT_EQ(ready->view_ready().view_id(), 7u);
  EXPECT_GT(meshes, 0u);
  ws.send(explosion(1, 16, y, 16));
  auto result = ws.wait_for([](const wire::Envelope& m) { return m.has_edit_result(); });
  ASSERT_TRUE(result);
  EXPECT_EQ(result->edit_result().status(), wire::EditResult::ACCEPTED);
  EXPECT_TRUE(ws.wait_for([](const wire::Envelope& m) {
    return m.has_chunk_mesh() && m.chunk_mesh().base_version() != 0;
  })) << "no delta for the crater";
  // The mesh bytes are counted by level and kind (what a LOD view's traffic is made of).
  auto m = metrics(server.metrics_port());
  EXPECT_GT((m["voxeld_mesh_payload_bytes_total{level=\"0\",kind=\"full\"}"]), 0);
  EXPECT_GE((m["voxeld_mesh_messages_total{level=\"0\",kind=\"full\"}"]), double(meshes));
  EXPECT_GE((m["voxeld_mesh_messages_total{level=\"0\",kind=\"delta\"}"]), 1);
}

TEST(WebSocket, ATcpPlayerAndABrowserSeeEachOthersEdits) {
  ServerProcess server({"--http-port", "auto", "--in-memory"});
  const float y = surface_y(40, 40);
  auto tcp = player(server, "tcp");
  view(*tcp, 40, y, 40, 1);
  WsClient ws(server.http_port());
  ws.send(client::make_hello("browser"));
  ws.send(client::make_set_view(40, y, 40, 1, 1));
  ASSERT_TRUE(ws.wait_for([](const wire::Envelope& m) { return m.has_view_ready(); }));
  // The browser's edit reaches the TCP player as a delta...
  ws.send(explosion(1, 40, y, 40));
  EXPECT_TRUE(wait_for(*tcp, [](const wire::Envelope& m) {
    return m.has_chunk_mesh() && m.chunk_mesh().base_version() != 0;
  }));
  // ... and the TCP player's reaches the browser.
  auto result = edit_and_wait(*tcp, explosion(2, 44, y, 44));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->edit_result().status(), wire::EditResult::ACCEPTED);
  bool seen = false;
  ws.wait_for([&](const wire::Envelope& m) {
    if (!m.has_chunk_mesh() || m.chunk_mesh().base_version() == 0) return false;
    seen = true;
    return true;
  });
  EXPECT_TRUE(seen);
}

TEST(WebSocket, BadMessagesCloseWithTheirCodeAndOthersPlayOn) {
  ServerProcess server(
      {"--http-port", "auto", "--in-memory", "--metrics-port", "0", "--frame-timeout-ms", "1000"});
  const uint16_t http = server.http_port();
  auto bystander = player(server, "bystander");
  {  // A message over the frame limit (64 KiB): too big.
    WsClient ws(http);
    ws.send_bytes(std::string(70 * 1024, 'x'));
    EXPECT_EQ(ws.until_closed(), static_cast<uint16_t>(websocket::close_code::too_big));
  }
  {  // The same in fragments, each under the limit.
    WsClient ws(http);
    ws.ws.auto_fragment(true);
    ws.ws.write_buffer_bytes(4096);
    ws.send_bytes(std::string(70 * 1024, 'x'));
    EXPECT_EQ(ws.until_closed(), static_cast<uint16_t>(websocket::close_code::too_big));
  }
  {  // A text message: an Error, then unsupported data.
    WsClient ws(http);
    ws.ws.text(true);
    ws.send_bytes("hello");
    std::optional<wire::Envelope> error;
    while (auto m = ws.receive()) {
      if (m->has_error()) error = m;
    }
    ASSERT_TRUE(error);
    EXPECT_EQ(error->error().code(), wire::Error::MALFORMED);
    EXPECT_EQ(ws.close_code, static_cast<uint16_t>(websocket::close_code::unknown_data));
  }
  {  // A ping flood: policy violation.
    WsClient ws(http);
    for (int i = 0; i < 50; ++i) {
      bool done = false;
      ws.ws.async_ping({}, [&](beast::error_code) { done = true; });
      run_until(ws.io, done);
    }
    EXPECT_EQ(ws.until_closed(), static_cast<uint16_t>(websocket::close_code::policy_error));
  }
  {  // A message started and never finished: closed after the frame timeout.
    WsClient ws(http);
    bool done = false;
    const std::string part(100, 'x');
    ws.ws.async_write_some(false, asio::buffer(part),
                           [&](beast::error_code, size_t) { done = true; });
    run_until(ws.io, done);
    EXPECT_NE(ws.until_closed(), 0);
  }
  // Nobody else noticed.
  const float y = surface_y(16, 16);
  auto result = edit_and_wait(*bystander, explosion(1, 16, y, 16));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->edit_result().status(), wire::EditResult::ACCEPTED);
  auto m = metrics(server.metrics_port());
  EXPECT_EQ(m["voxeld_websocket_closed_total{reason=\"too_big\"}"], 2);
  EXPECT_EQ(m["voxeld_websocket_closed_total{reason=\"text\"}"], 1);
  EXPECT_EQ(m["voxeld_websocket_closed_total{reason=\"ping_flood\"}"], 1);
  EXPECT_EQ(m["voxeld_websocket_closed_total{reason=\"frame_timeout\"}"], 1);
}

TEST(Http, ServesTheViewerAndRefusesWhatLeavesItsRootWithAClearStatus) {
  TempDir files("http_root");
  std::filesystem::create_directories(files.path() / "assets");
  std::ofstream(files.path() / "index.html") << "<html>voxeld viewer</html>";
  std::ofstream(files.path() / "assets" / "viewer.js") << "console.log(1)";
  ServerProcess server({"--http-port", "auto", "--in-memory", "--metrics-port", "0", "--http-root",
                        files.path().string()});
  const uint16_t port = server.http_port();
  const auto get = [&](const std::string& target, const std::string& method = "GET") {
    return http_exchange(
        port, method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  };
  const std::string index = get("/");
  EXPECT_TRUE(index.starts_with("HTTP/1.1 200")) << index;
  EXPECT_NE(index.find("voxeld viewer"), std::string::npos);
  EXPECT_NE(index.find("text/html"), std::string::npos);
  const std::string js = get("/assets/viewer.js");
  EXPECT_TRUE(js.starts_with("HTTP/1.1 200")) << js;
  // A load balancer's health check: a single node takes players while it runs.
  const std::string health = get("/healthz?probe=1");
  EXPECT_TRUE(health.starts_with("HTTP/1.1 200")) << health;
  EXPECT_TRUE(health.ends_with("\r\n\r\nok\n")) << health;
  EXPECT_NE(health.find("no-store"), std::string::npos) << health;
  EXPECT_NE(js.find("text/javascript"), std::string::npos);
  const std::string head = get("/assets/viewer.js", "HEAD");
  EXPECT_TRUE(head.starts_with("HTTP/1.1 200")) << head;
  EXPECT_EQ(head.find("console.log"), std::string::npos);
  for (const char* bad : {"/../index.html", "/%2e%2e/%2e%2e/etc/passwd", "/assets/..%2f..%2fx",
                          "/a%00b", "/assets//viewer.js"}) {
    EXPECT_TRUE(get(bad).starts_with("HTTP/1.1 400")) << bad;
  }
  EXPECT_TRUE(get("/nosuch.js").starts_with("HTTP/1.1 404"));
  const std::string post = get("/", "POST");
  EXPECT_TRUE(post.starts_with("HTTP/1.1 405"));
  EXPECT_NE(post.find("Allow: GET, HEAD"), std::string::npos) << post;
  std::ofstream(files.path() / ".env") << "SECRET=1";
  EXPECT_TRUE(get("/.env").starts_with("HTTP/1.1 400"));
  std::filesystem::create_symlink("/etc/hostname", files.path() / "outside.txt");
  EXPECT_TRUE(get("/outside.txt").starts_with("HTTP/1.1 404")) << "a link out of the root";
  EXPECT_TRUE(get("/ws").starts_with("HTTP/1.1 426"));
  const std::string huge = http_exchange(port, "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " +
                                                   std::string(16 * 1024, 'a') + "\r\n\r\n");
  EXPECT_TRUE(huge.starts_with("HTTP/1.1 431")) << huge.substr(0, 80);
  WsClient foreign(port, "http://evil.example");
  EXPECT_TRUE(foreign.handshake_error) << "an upgrade from another origin was accepted";
  WsClient own(port, "http://127.0.0.1:" + std::to_string(port));
  EXPECT_FALSE(own.handshake_error) << own.handshake_error.message();
  // A page whose name an attacker points at 127.0.0.1 (DNS rebinding): its Origin matches
  // its Host, but a loopback server takes upgrades only to loopback names.
  const std::string p = std::to_string(port);
  const std::string rebound = http_exchange(
      port, "GET /ws HTTP/1.1\r\nHost: evil.example:" + p + "\r\nOrigin: http://evil.example:" + p +
                "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"
                "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n");
  EXPECT_TRUE(rebound.starts_with("HTTP/1.1 403")) << rebound.substr(0, 80);
  auto m = metrics(server.metrics_port());
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"bad_request\"}"], 7);  // 6 paths and /ws
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"not_found\"}"], 2);
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"bad_method\"}"], 1);
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"header_too_big\"}"], 1);
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"origin\"}"], 2);
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"timeout\"}"], 0);
}

TEST(Http, AnIdleKeepAliveConnectionIsClosedQuietlyAndIsNoSlowRequest) {
  ServerProcess server({"--http-port", "auto", "--in-memory", "--metrics-port", "0"});
  const auto start = std::chrono::steady_clock::now();
  // One request kept alive, then nothing: closed within the keep-alive idle time.
  const std::string response =
      http_exchange(server.http_port(), "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", 10s);
  EXPECT_TRUE(response.starts_with("HTTP/1.1 200")) << response.substr(0, 80);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 4s * kSlow);
  auto m = metrics(server.metrics_port());
  EXPECT_EQ(m["voxeld_http_refused_total{reason=\"timeout\"}"], 0);
}

TEST(Http, ASlowRequestIsClosedAtTheRequestTimeoutWhilePlayersGoOn) {
  ServerProcess server({"--http-port", "auto", "--in-memory", "--handshake-timeout-ms", "500"});
  asio::io_context io;
  std::vector<asio::ip::tcp::socket> slow;
  for (int i = 0; i < 20; ++i) {
    slow.emplace_back(io);
    slow.back().connect({asio::ip::make_address("127.0.0.1"), server.http_port()});
    asio::write(slow.back(), asio::buffer(std::string("GET / HTTP/1.1\r\nHost: 127.0.0")));
  }
  // A browser's page still loads meanwhile.
  const std::string page =
      http_exchange(server.http_port(), "GET / HTTP/1.1\r\nHost: h\r\nConnection: close\r\n\r\n");
  EXPECT_TRUE(page.starts_with("HTTP/1.1 200")) << page;
  size_t closed = 0;
  for (auto& s : slow) {
    std::array<char, 64> buf;
    bool done = false;
    s.async_read_some(asio::buffer(buf), [&](boost::system::error_code ec, size_t) {
      closed += ec ? 1 : 0;
      done = true;
    });
    run_until(io, done, 5s);
  }
  EXPECT_EQ(closed, slow.size());
}

}  // namespace
}  // namespace vox::test

namespace vox::test {
namespace {

// Hello on `ws`; whether it was welcomed (else refused with TOO_MANY_CONNECTIONS).
bool welcomed(WsClient& ws) {
  if (ws.handshake_error) return false;
  ws.send(client::make_hello("browser"));
  auto m = ws.wait_for([](const wire::Envelope& e) { return e.has_welcome() || e.has_error(); });
  if (m && m->has_error()) {
    EXPECT_EQ(m->error().code(), wire::Error::TOO_MANY_CONNECTIONS);
  }
  return m && m->has_welcome();
}

// Behind a TLS proxy every browser came from the proxy's address, so one address's cap
// held the whole server. A trusted proxy's players are capped by the client it names.
TEST(WebSocket, BehindATrustedProxyEachClientIsCappedByItsOwnAddress) {
  ServerProcess server({"--http-port", "auto", "--in-memory", "--max-per-address", "1",
                        "--http-trusted-proxy", "127.0.0.1", "--http-allow-origin",
                        "https://play.example"});
  // Pages of https://play.example, whose upgrades the proxy passes on with their Host.
  WsClient a(server.http_port(), "https://play.example", "203.0.113.5", "play.example");
  WsClient b(server.http_port(), "https://play.example", "198.51.100.1, 203.0.113.6",
             "play.example");
  EXPECT_TRUE(welcomed(a));
  EXPECT_TRUE(welcomed(b));
  WsClient again(server.http_port(), {}, "203.0.113.5");
  EXPECT_FALSE(welcomed(again)) << "a second player from 203.0.113.5";
  WsClient proxy_itself(server.http_port());  // no header: the proxy's own address
  EXPECT_TRUE(welcomed(proxy_itself));
  // An entry that is not an address is refused at the upgrade.
  WsClient garbled(server.http_port(), {}, "not-an-address");
  EXPECT_TRUE(garbled.handshake_error);
  // A page naming another host is refused (DNS rebinding), straight or through the proxy.
  WsClient rebound(server.http_port(), "http://evil.example", {}, "evil.example");
  EXPECT_TRUE(rebound.handshake_error);
  WsClient rebound_via_proxy(server.http_port(), "http://evil.example", "203.0.113.9",
                             "evil.example");
  EXPECT_TRUE(rebound_via_proxy.handshake_error);
}

// Without --http-trusted-proxy the header is anybody's to write: it is ignored.
TEST(WebSocket, XForwardedForFromAnUntrustedPeerIsIgnored) {
  ServerProcess server({"--http-port", "auto", "--in-memory", "--max-per-address", "1"});
  WsClient a(server.http_port(), {}, "203.0.113.5");
  WsClient b(server.http_port(), {}, "203.0.113.6");
  EXPECT_TRUE(welcomed(a));
  EXPECT_FALSE(welcomed(b)) << "127.0.0.1's second player";
}

}  // namespace
}  // namespace vox::test
