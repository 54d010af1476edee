// The TCP transport of a session (server/net/tcp_connection.hpp) on a real loopback
// socket, with no session around it: whole frames in, a frame over the limit refused
// before it is buffered, a trickled frame timed out, appended messages written in order.
#include "server/net/tcp_connection.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio.hpp>
#include <future>
#include <thread>

#include "proto/framing.hpp"
#include "tests/alloc_counter.hpp"
#include "tests/run_io_until.hpp"

namespace vox::net {
namespace {

namespace asio = boost::asio;
using namespace std::chrono_literals;

struct Recorder : Connection::Events {
  std::vector<std::vector<uint8_t>> messages;
  std::vector<std::pair<wire::Error::Code, std::string>> stream_errors;
  size_t written = 0;
  int closed = 0, write_timeouts = 0;
  bool on_message(std::span<const uint8_t> body) override {
    messages.emplace_back(body.begin(), body.end());
    return true;
  }
  void on_stream_error(wire::Error::Code code, const std::string& why) override {
    stream_errors.emplace_back(code, why);
  }
  void on_written(size_t bytes) override { written += bytes; }
  void on_write_timeout() override { ++write_timeouts; }
  void on_closed() override { ++closed; }
};

// A connected pair on 127.0.0.1: the server side as a TcpConnection, the client side raw.
struct Pair {
  explicit Pair(size_t max_frame = 64, std::chrono::milliseconds frame_timeout = 10s) {
    asio::ip::tcp::acceptor acceptor(io, {asio::ip::make_address("127.0.0.1"), 0});
    client.connect(acceptor.local_endpoint());
    connection = std::make_unique<TcpConnection>(acceptor.accept(Strand(io.get_executor())),
                                                 max_frame, frame_timeout);
  }
  template <class Done>
  void run_until(Done&& done) {
    test::run_io_until(io, done);
  }
  asio::io_context io;
  asio::ip::tcp::socket client{io};
  std::unique_ptr<TcpConnection> connection;
  std::shared_ptr<Recorder> events = std::make_shared<Recorder>();
};

std::vector<uint8_t> frame(std::vector<uint8_t> body) {
  std::vector<uint8_t> out;
  proto::append_frame(body, out);
  return out;
}

TEST(TcpConnection, DeliversWholeFramesAndRefusesOneOverTheLimitBeforeBufferingIt) {
  Pair p(64);
  std::vector<uint8_t> bytes = frame({1, 2, 3});
  const auto second = frame({4});
  bytes.insert(bytes.end(), second.begin(), second.end());
  bytes.insert(bytes.end(), {0xFF, 0xFF, 0xFF, 0x7F});  // a length far over the limit
  asio::write(p.client, asio::buffer(bytes));
  asio::post(p.connection->strand(), [&] { p.connection->read(p.events); });
  p.run_until([&] { return !p.events->stream_errors.empty(); });
  ASSERT_EQ(p.events->messages.size(), 2u);
  EXPECT_EQ(p.events->messages[0], (std::vector<uint8_t>{1, 2, 3}));
  EXPECT_EQ(p.events->messages[1], (std::vector<uint8_t>{4}));
  ASSERT_EQ(p.events->stream_errors.size(), 1u);
  EXPECT_EQ(p.events->stream_errors[0].first, wire::Error::FRAME_TOO_LARGE);
  EXPECT_LT(p.connection->bytes_buffered(), 64u);
}

TEST(TcpConnection, AFrameNotCompletedInTimeIsAStreamError) {
  Pair p(64, 100ms);
  const std::vector<uint8_t> partial = {10, 0, 0, 0, 1, 2};  // 2 of its 10 bytes
  asio::write(p.client, asio::buffer(partial));
  asio::post(p.connection->strand(), [&] { p.connection->read(p.events); });
  p.run_until([&] { return !p.events->stream_errors.empty(); });
  ASSERT_EQ(p.events->stream_errors.size(), 1u);
  EXPECT_EQ(p.events->stream_errors[0].first, wire::Error::FRAME_TIMEOUT);
  EXPECT_TRUE(p.events->messages.empty());
}

TEST(TcpConnection, AppendedMessagesAreWrittenInOrderInOneWrite) {
  Pair p;
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(7);
  const std::vector<uint8_t> raw = {9, 9};
  asio::post(p.connection->strand(), [&] {
    p.connection->append(ping);
    p.connection->append_serialized(raw);
    EXPECT_EQ(p.connection->pending_bytes(), 4 + ping.ByteSizeLong() + 4 + raw.size());
    p.connection->write(p.events, 5s);
    EXPECT_TRUE(p.connection->writing());
  });
  p.run_until([&] { return p.events->written > 0; });
  EXPECT_EQ(p.events->written, 4 + ping.ByteSizeLong() + 4 + raw.size());
  EXPECT_FALSE(p.connection->writing());
  EXPECT_EQ(p.connection->pending_bytes(), 0u);
  std::vector<uint8_t> got(p.events->written);
  asio::read(p.client, asio::buffer(got));
  proto::FrameDecoder decoder(64);
  decoder.feed(got);
  wire::Envelope back;
  const auto first = decoder.next();
  ASSERT_TRUE(first && back.ParseFromArray(first->data(), static_cast<int>(first->size())));
  EXPECT_EQ(back.ping().nonce(), 7u);
  EXPECT_EQ(decoder.next(), raw);
  EXPECT_EQ(p.events->write_timeouts, 0);
}

// The session writer is a hot path: once warm, a write allocates nothing. (Its socket's
// executor was a type-erased strand, which every asynchronous operation copied to the heap.)
TEST(TcpConnection, AWriteOnceWarmAllocatesNothing) {
  Pair p;
  const std::vector<uint8_t> raw(900, 1);
  std::atomic<size_t> received{0};
  std::thread reader([&] {
    std::vector<uint8_t> buffer(1 << 16);
    boost::system::error_code ec;
    while (!ec) received += p.client.read_some(asio::buffer(buffer), ec);
  });
  size_t allocations = 0;
  for (int round = 0; round < 4; ++round) {  // three to warm up, then the one counted
    if (round == 3) allocations = test::allocations_on_this_thread();
    const size_t before = p.events->written;
    // Called while the io_context is not running: nothing else is on the strand.
    for (int i = 0; i < 64; ++i) p.connection->append_serialized(raw);
    p.connection->write(p.events, 5s);
    p.run_until([&] { return p.events->written > before; });
  }
  EXPECT_EQ(test::allocations_on_this_thread() - allocations, 0u);
  p.run_until([&] { return received.load() == p.events->written; });
  p.client.shutdown(asio::ip::tcp::socket::shutdown_both);
  reader.join();
  EXPECT_EQ(received.load(), 4 * 64 * (4 + raw.size()));
}

// A view's first meshes fill a write of up to max_bytes_in_flight; the buffer kept that
// capacity, so a thousand sessions held 256 KiB each long after their views were sent.
TEST(TcpConnection, AfterABurstASmallWriteGivesTheBuffersMemoryBack) {
  Pair p;
  std::atomic<size_t> received{0};
  std::thread reader([&] {
    std::vector<uint8_t> buffer(1 << 16);
    boost::system::error_code ec;
    while (!ec) received += p.client.read_some(asio::buffer(buffer), ec);
  });
  const auto write = [&](size_t messages, size_t bytes) {
    const std::vector<uint8_t> raw(bytes, 7);
    const size_t before = p.events->written;
    for (size_t i = 0; i < messages; ++i) p.connection->append_serialized(raw);
    p.connection->write(p.events, 5s);
    p.run_until([&] { return p.events->written > before; });
  };
  write(256, 1000);  // a burst: 257 KB
  EXPECT_GT(p.connection->memory_bytes(), 256u * 1024);
  write(2, 1000);  // steady play: small writes
  EXPECT_LT(p.connection->memory_bytes(), 64u * 1024) << "the burst's capacity was kept";
  p.run_until([&] { return received.load() == p.events->written; });
  p.client.shutdown(asio::ip::tcp::socket::shutdown_both);
  reader.join();
}

TEST(TcpConnection, ThePeerClosingEndsTheReadOnce) {
  Pair p;
  asio::post(p.connection->strand(), [&] { p.connection->read(p.events); });
  p.client.close();
  p.run_until([&] { return p.events->closed > 0; });
  EXPECT_EQ(p.events->closed, 1);
  p.connection->close();
  EXPECT_FALSE(p.connection->open());
}

}  // namespace
}  // namespace vox::net
