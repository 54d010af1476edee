// A session's WebSocket connection (the browser's transport; docs/PROTOCOL.md 4.1): one
// binary message carries exactly one Envelope, no length prefix. The upgrade was accepted
// already (HttpFront). A message over `max_frame_bytes` is refused as it arrives
// (FRAME_TOO_LARGE, close code 1009), a text message too (close code 1003), a message that
// has started must finish within `frame_timeout` (FRAME_TIMEOUT), and more pings than
// kMaxPingsPerSecond (with a burst of as many) close the connection (close code 1008).
// A write sends every message appended since the last one, each as its own binary
// message, under one deadline; their operations' memory is reused (handler_memory.hpp).
// Strand only (see connection.hpp): the stream's executor is
// the strand its connection was accepted on, and strand() wraps it, so the session's
// handlers and the stream's run one at a time.
//
// The stream and its buffers live in a shared State that each asynchronous operation
// keeps alive, so that close() can send a close frame after the session has gone.
#pragma once

#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <memory>
#include <optional>
#include <vector>

#include "server/net/connection.hpp"
#include "server/net/handler_memory.hpp"
#include "server/net/server_counters.hpp"

namespace vox::net {

using WsStream = boost::beast::websocket::stream<
    boost::beast::basic_stream<boost::asio::ip::tcp, Strand, boost::beast::unlimited_rate_policy>>;

class WsConnection final : public Connection {
 public:
  static constexpr double kMaxPingsPerSecond = 10;

  // `ws` has completed its handshake (its executor is the strand). `counters`: outlive it.
  WsConnection(WsStream ws, size_t max_frame_bytes, std::chrono::milliseconds frame_timeout,
               ServerCounters& counters);
  ~WsConnection() override;

  Strand& strand() override;
  bool open() const override;
  void read(std::shared_ptr<Events> owner) override;
  bool writing() const override;
  void append(const google::protobuf::MessageLite& message) override;
  void append_serialized(std::span<const uint8_t> body) override;
  size_t pending_bytes() const override;
  void write(std::shared_ptr<Events> owner, std::chrono::milliseconds deadline) override;
  // Sends a close frame (with the code a stream error chose, else "going away") and
  // closes the socket once it is out or after a second.
  void close() override;
  size_t memory_bytes() const override;
  size_t bytes_buffered() const override;

 private:
  struct State;
  static void ping_flood(State& s, Events& owner);  // too many pings: closes
  void read_some(std::shared_ptr<Events> owner);
  void watch_partial_message(std::shared_ptr<Events> owner);
  void write_next(std::shared_ptr<Events> owner, size_t index, size_t written);
  void stream_error(const std::shared_ptr<Events>& owner, wire::Error::Code code,
                    boost::beast::websocket::close_code close, const std::string& why);

  std::shared_ptr<State> state_;
};

}  // namespace vox::net
