// A simulated player's connection to voxeld: the transport under one SimPlayer, so the
// player's logic (view, edits, decoding, latency) does not depend on how the Envelopes
// travel. TCP sends each as a length-prefixed frame (docs/PROTOCOL.md 4.1). A link is used from its
// player's strand only: its socket's executor is that strand, so every completion handler runs
// there too.
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
  std::string source;  // the local address to connect from; empty: any
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
inline std::unique_ptr<PlayerLink> make_player_link(PlayerStrand strand, LinkTarget target) {
  return make_tcp_link(std::move(strand), std::move(target));
}

}  // namespace vox::loadtest
