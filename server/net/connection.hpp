// What a session needs of its connection (the transport seam): whole messages in, whole
// messages out, and the transport's own rules (a frame's size and time, a write's time).
// The session decides what to send and when; the connection frames, writes and reads.
// TCP (tcp_connection.hpp) sends 4-byte length-prefixed frames; another transport
// implements the same members. Every member runs on the connection's strand, which the
// session shares; each asynchronous operation keeps its `owner` alive until its handler
// has run (the session owns the connection).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "server/net/asio.hpp"
#include "voxel.pb.h"

namespace google::protobuf {
class MessageLite;
}

namespace vox::net {

// After a write: empties `buffer` and keeps its capacity for the next write, unless a
// burst (a view's first meshes: up to max_bytes_in_flight) grew it past kKeptWriteBytes
// and this write used under a quarter of it. Then the memory goes back: kept, a thousand
// sessions held 256 KiB each long after their views were sent.
inline constexpr size_t kKeptWriteBytes = 32 * 1024;
template <class Buffer>
void clear_write_buffer(Buffer& buffer) {
  if (buffer.capacity() > kKeptWriteBytes && buffer.size() * 4 < buffer.capacity()) {
    Buffer().swap(buffer);
    return;
  }
  buffer.clear();
}

class Connection {
 public:
  // What the connection tells its session, on the strand.
  class Events {
   public:
    virtual ~Events() = default;
    // One whole message (an Envelope's bytes). False: read no more until read() again.
    virtual bool on_message(std::span<const uint8_t> body) = 0;
    // The stream broke a transport rule (a frame over the limit, one not completed in
    // time): the session sends the Error and closes.
    virtual void on_stream_error(wire::Error::Code code, const std::string& why) = 0;
    // The write finished: `bytes` went out (another may start).
    virtual void on_written(size_t bytes) = 0;
    // The write did not finish within its deadline: the peer stopped reading.
    virtual void on_write_timeout() = 0;
    // The peer closed, or reading or writing failed (also after close(): idempotent).
    virtual void on_closed() = 0;
  };

  virtual ~Connection() = default;
  virtual Strand& strand() = 0;
  virtual bool open() const = 0;

  // Handles the messages already received, then reads on, until on_message says stop, a
  // stream error, or the end.
  virtual void read(std::shared_ptr<Events> owner) = 0;

  // The next write: messages are appended while no write is in flight, then written.
  virtual bool writing() const = 0;
  virtual void append(const google::protobuf::MessageLite& message) = 0;
  virtual void append_serialized(std::span<const uint8_t> body) = 0;  // an Envelope's bytes
  virtual size_t pending_bytes() const = 0;
  // Writes what was appended (nothing: no-op); a deadline of zero: none.
  virtual void write(std::shared_ptr<Events> owner, std::chrono::milliseconds deadline) = 0;

  virtual void close() = 0;                   // at once; pending operations end
  virtual size_t memory_bytes() const = 0;    // its buffers and a partial message
  virtual size_t bytes_buffered() const = 0;  // received, not yet a whole message
};

}  // namespace vox::net
