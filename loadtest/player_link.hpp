// A simulated player's connection to voxeld: the transport under one SimPlayer, so the
// player's logic (view, edits, decoding, latency) is the same code over both. TCP sends
// each Envelope as a length-prefixed frame; a WebSocket (GET /ws on the HTTP port) as one
// binary message (docs/PROTOCOL.md 4.1). A link is used from its player's strand only: its
// socket's executor is that strand, so every completion handler runs there too.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "client/asio.hpp"

namespace vox::loadtest {

using PlayerStrand = boost::asio::strand<boost::asio::io_context::executor_type>;

struct LinkTarget {
  std::string host;
  uint16_t port = 0;
  std::string source;      // the local address to connect from; empty: any
  bool websocket = false;  // ws://host:port/ws instead of TCP
};

class PlayerLink {
 public:
  // An empty error is success. Each handler keeps the link's owner (and so the link) alive.
  using Done = std::function<void(const std::string& error)>;
  // `wire_bytes`: what came off the connection (frames and their headers), for bytes/s.
  using Read = std::function<void(const std::string& error, size_t wire_bytes)>;

  virtual ~PlayerLink() = default;
  // Connects (and for a WebSocket, upgrades); `done` once it can carry Envelopes.
  virtual void connect(Done done) = 0;
  // Writes one serialized Envelope; the caller starts the next write after `done`.
  virtual void write(std::span<const uint8_t> envelope, Done done) = 0;
  // Reads what the server sent next; then next_message() gives every Envelope it completed.
  virtual void read(Read done) = 0;
  // The next whole Envelope's bytes since the last read (valid until the next call), or
  // nullopt: read again, unless message_error() says the stream is broken.
  virtual std::optional<std::span<const uint8_t>> next_message() = 0;
  virtual const std::string& message_error() const = 0;
  // Closes at once (no close handshake); pending handlers complete with an error.
  virtual void close() = 0;
};

std::unique_ptr<PlayerLink> make_tcp_link(PlayerStrand strand, LinkTarget target);
std::unique_ptr<PlayerLink> make_ws_link(PlayerStrand strand, LinkTarget target);
inline std::unique_ptr<PlayerLink> make_player_link(PlayerStrand strand, LinkTarget target) {
  return target.websocket ? make_ws_link(std::move(strand), std::move(target))
                          : make_tcp_link(std::move(strand), std::move(target));
}

// Opens `socket` and binds it to `source` (a spread source address, LinkTarget::source)
// before it connects to `to`; nothing when `source` is empty. The error, or empty.
template <class Socket>
std::string bind_source(Socket& socket, const boost::asio::ip::tcp::endpoint& to,
                        const std::string& source) {
  if (source.empty()) return {};
  boost::system::error_code ec;
  const auto from = boost::asio::ip::make_address(source, ec);
  if (!ec) socket.open(to.protocol(), ec);
  if (!ec) socket.bind({from, 0}, ec);
  return ec ? "cannot bind a spread source address: " + ec.message() : std::string();
}

// The bytes of a server's WebSocket message of `payload` bytes on the wire: voxeld sends
// each as one unmasked frame (no fragments), with a 2-, 4- or 10-byte header (RFC 6455 5.2).
size_t ws_server_frame_bytes(size_t payload);

}  // namespace vox::loadtest
