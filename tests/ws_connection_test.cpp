// The WebSocket transport of a session (server/net/ws_connection.hpp) on a real loopback
// socket, with no session or HTTP front around it: appended messages go out as one binary
// message each and in order, a write once warm allocates nothing, and a peer that stops
// reading is a write timeout.
#include "server/net/ws_connection.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio.hpp>
#include <thread>

#include "tests/alloc_counter.hpp"
#include "tests/run_io_until.hpp"

namespace vox::net {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using namespace std::chrono_literals;

struct Recorder : Connection::Events {
  size_t written = 0;
  int closed = 0, write_timeouts = 0;
  bool on_message(std::span<const uint8_t>) override { return true; }
  void on_stream_error(wire::Error::Code, const std::string&) override {}
  void on_written(size_t bytes) override { written += bytes; }
  void on_write_timeout() override { ++write_timeouts; }
  void on_closed() override { ++closed; }
};

// A connected pair on 127.0.0.1: the server side a WsConnection run by `io` on this
// thread, the client a blocking Beast stream of its own io_context (used from one thread
// at a time).
struct Pair {
  Pair() {
    asio::ip::tcp::acceptor acceptor(io, {asio::ip::make_address("127.0.0.1"), 0});
    std::thread client_side([&, at = acceptor.local_endpoint()] {
      client.next_layer().connect(at);
      client.handshake("127.0.0.1", "/ws");
    });
    WsStream ws(acceptor.accept(Strand(io.get_executor())));
    ws.accept();
    client_side.join();
    connection = std::make_unique<WsConnection>(std::move(ws), 1 << 20, 10s, counters);
  }
  ~Pair() {
    connection.reset();
    io.restart();
    io.run_for(50ms);
  }
  template <class Done>
  void run_until(Done&& done) {
    test::run_io_until(io, done);
  }
  // Appends `count` messages of `bytes` each and writes them (called while `io` is not
  // running: nothing else is on the strand).
  void send(size_t count, size_t bytes) {
    raw.assign(bytes, 0x5a);
    for (size_t i = 0; i < count; ++i) connection->append_serialized(raw);
    connection->write(events, 5s);
  }
  asio::io_context io;
  asio::io_context client_io;
  websocket::stream<asio::ip::tcp::socket> client{client_io};
  ServerCounters counters;
  std::unique_ptr<WsConnection> connection;
  std::shared_ptr<Recorder> events = std::make_shared<Recorder>();
  std::vector<uint8_t> raw;
};

TEST(WsConnection, AppendedMessagesGoOutOneBinaryMessageEachInOrder) {
  Pair p;
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(7);
  const std::vector<uint8_t> raw = {9, 9, 9};
  asio::post(p.connection->strand(), [&] {
    p.connection->append(ping);
    p.connection->append_serialized(raw);
    EXPECT_EQ(p.connection->pending_bytes(), ping.ByteSizeLong() + raw.size());
    p.connection->write(p.events, 5s);
  });
  p.run_until([&] { return p.events->written > 0; });
  EXPECT_EQ(p.events->written, ping.ByteSizeLong() + raw.size());
  EXPECT_EQ(p.connection->pending_bytes(), 0u);
  beast::flat_buffer got;
  p.client.read(got);
  EXPECT_TRUE(p.client.got_binary());
  wire::Envelope back;
  ASSERT_TRUE(back.ParseFromArray(got.cdata().data(), static_cast<int>(got.size())));
  EXPECT_EQ(back.ping().nonce(), 7u);
  got.clear();
  p.client.read(got);
  EXPECT_EQ(got.size(), raw.size());
}

// The session writer is a hot path: once its buffers have grown, writing a batch of
// messages allocates nothing, whatever the number of messages.
TEST(WsConnection, WritingMessagesOnceWarmAllocatesNothing) {
  Pair p;
  constexpr size_t kMessages = 64, kBytes = 900;
  std::atomic<size_t> received{0};
  std::thread reader([&] {
    beast::flat_buffer got;
    boost::system::error_code ec;
    while (!ec) {
      p.client.read(got, ec);
      got.clear();
      if (!ec) ++received;
    }
  });
  for (int round = 0; round < 3; ++round) {  // warm: buffers, the strand, Beast's ops
    const size_t before = p.events->written;
    p.send(kMessages, kBytes);
    p.run_until([&] { return p.events->written == before + kMessages * kBytes; });
  }
  const size_t allocations = test::allocations_on_this_thread();
  const size_t before = p.events->written;
  p.send(kMessages, kBytes);
  p.run_until([&] { return p.events->written == before + kMessages * kBytes; });
  EXPECT_EQ(test::allocations_on_this_thread() - allocations, 0u)
      << "allocations for a write of " << kMessages << " messages";
  EXPECT_EQ(p.events->written, 4 * kMessages * kBytes);
  p.run_until([&] { return received.load() == 4 * kMessages; });
  p.client.next_layer().shutdown(asio::ip::tcp::socket::shutdown_both);
  reader.join();
  EXPECT_EQ(received.load(), 4 * kMessages);
}

// A browser tab that stops reading (a background tab, a stalled network): the write does
// not finish and the session hears of it at the deadline, instead of buffering forever.
TEST(WsConnection, APeerThatStopsReadingIsAWriteTimeout) {
  Pair p;
  asio::post(p.connection->strand(), [&] {
    p.raw.assign(1 << 16, 1);
    for (int i = 0; i < 256; ++i) p.connection->append_serialized(p.raw);  // 16 MiB
    p.connection->write(p.events, 300ms);
  });
  p.run_until([&] { return p.events->write_timeouts > 0; });
  EXPECT_EQ(p.events->write_timeouts, 1);
  EXPECT_TRUE(p.connection->writing());
  asio::post(p.connection->strand(), [&] { p.connection->close(); });
  p.run_until([&] { return p.events->closed > 0; });
  EXPECT_FALSE(p.connection->open());
}

}  // namespace
}  // namespace vox::net
