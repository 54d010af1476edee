// A session's TCP connection: frames are a 4-byte little-endian length and an Envelope
// (proto/framing.hpp). A frame over `max_frame_bytes` is refused before it is buffered
// (FRAME_TOO_LARGE), and a frame that has started must finish within `frame_timeout`, so
// a client cannot hold a connection by trickling bytes (FRAME_TIMEOUT). Reads go through
// a 16 KiB buffer; a write sends every message appended since the last one in one
// async_write, under a deadline; their operations' memory is reused (handler_memory.hpp).
// Strand only (see connection.hpp).
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "proto/framing.hpp"
#include "server/net/connection.hpp"
#include "server/net/handler_memory.hpp"

namespace vox::net {

class TcpConnection final : public Connection {
 public:
  TcpConnection(StrandSocket socket, size_t max_frame_bytes,
                std::chrono::milliseconds frame_timeout);

  Strand& strand() override { return strand_; }
  bool open() const override { return socket_.is_open(); }
  void read(std::shared_ptr<Events> owner) override;
  bool writing() const override { return writing_; }
  void append(const google::protobuf::MessageLite& message) override;
  void append_serialized(std::span<const uint8_t> body) override;
  size_t pending_bytes() const override { return write_buffer_.size(); }
  void write(std::shared_ptr<Events> owner, std::chrono::milliseconds deadline) override;
  void close() override;
  size_t memory_bytes() const override {
    return write_buffer_.capacity() + decoder_.buffered() + read_buffer_.size() +
           HandlerMemory::bytes();
  }
  size_t bytes_buffered() const override { return decoder_.buffered(); }

 private:
  void read_some(std::shared_ptr<Events> owner);
  void watch_partial_frame(std::shared_ptr<Events> owner);

  HandlerMemory::Owner memory_ = HandlerMemory::make();  // for its operations
  StrandSocket socket_;
  Strand strand_;  // the socket's executor
  StrandTimer frame_timer_, write_timer_;
  const std::chrono::milliseconds frame_timeout_;
  proto::FrameDecoder decoder_;
  std::array<uint8_t, 16 * 1024> read_buffer_;
  bool reading_ = false;  // an async read is in flight
  // When the partial frame in decoder_ started (none: no partial frame).
  std::optional<std::chrono::steady_clock::time_point> partial_since_;
  bool frame_watch_ = false;           // frame_timer_ is armed for a partial frame
  std::vector<uint8_t> write_buffer_;  // the next write's frames; capacity reused
  bool writing_ = false;
  uint64_t write_seq_ = 0;  // of the write in flight
};

}  // namespace vox::net
