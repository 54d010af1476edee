#include "server/net/tcp_connection.hpp"

#include <spdlog/spdlog.h>

namespace vox::net {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;

TcpConnection::TcpConnection(StrandSocket socket, size_t max_frame_bytes,
                             std::chrono::milliseconds frame_timeout)
    : socket_(std::move(socket)),
      strand_(socket_.get_executor()),
      frame_timer_(strand_),
      write_timer_(strand_),
      frame_timeout_(frame_timeout),
      decoder_(max_frame_bytes) {}

// The frames already buffered first (after a pause), then more bytes.
void TcpConnection::read(std::shared_ptr<Events> owner) {
  bool completed = false;
  while (auto frame = decoder_.next()) {
    completed = true;
    if (!owner->on_message(*frame) || !open()) return;
  }
  if (!decoder_.error().empty()) {
    owner->on_stream_error(wire::Error::FRAME_TOO_LARGE, decoder_.error());
    return;
  }
  // A partial frame left after complete ones started in this read.
  if (decoder_.buffered() == 0) {
    partial_since_.reset();
  } else if (completed || !partial_since_) {
    partial_since_ = Clock::now();
  }
  watch_partial_frame(owner);
  read_some(std::move(owner));
}

void TcpConnection::read_some(std::shared_ptr<Events> owner) {
  if (reading_ || !open()) return;
  reading_ = true;
  socket_.async_read_some(asio::buffer(read_buffer_),
                          with_memory(memory_, [this, owner = std::move(owner)](
                                                   boost::system::error_code ec, size_t n) mutable {
                            reading_ = false;
                            if (ec) {
                              owner->on_closed();
                              return;
                            }
                            decoder_.feed({read_buffer_.data(), n});
                            read(std::move(owner));
                          }));
}

void TcpConnection::watch_partial_frame(std::shared_ptr<Events> owner) {
  if (!partial_since_ || frame_watch_) return;
  frame_watch_ = true;
  frame_timer_.expires_at(*partial_since_ + frame_timeout_);
  frame_timer_.async_wait(
      with_memory(memory_, [this, owner = std::move(owner)](boost::system::error_code ec) mutable {
        frame_watch_ = false;
        if (ec || !open() || !partial_since_) return;
        if (Clock::now() >= *partial_since_ + frame_timeout_) {
          owner->on_stream_error(wire::Error::FRAME_TIMEOUT,
                                 "a frame was not completed within the frame timeout");
          return;
        }
        watch_partial_frame(std::move(owner));  // a later frame is partial now: watch it
      }));
}

void TcpConnection::append(const google::protobuf::MessageLite& message) {
  proto::append_framed(message, write_buffer_);
}

void TcpConnection::append_serialized(std::span<const uint8_t> body) {
  proto::append_frame(body, write_buffer_);
}

void TcpConnection::write(std::shared_ptr<Events> owner, std::chrono::milliseconds deadline) {
  if (writing_ || write_buffer_.empty() || !open()) return;
  writing_ = true;
  const uint64_t seq = ++write_seq_;
  if (deadline.count() > 0) {
    write_timer_.expires_after(deadline);
    // A deadline that fell due as its write finished is not the next write's.
    write_timer_.async_wait(with_memory(memory_, [this, owner, seq](boost::system::error_code ec) {
      if (!ec && writing_ && write_seq_ == seq) owner->on_write_timeout();
    }));
  }
  asio::async_write(socket_, asio::buffer(write_buffer_),
                    with_memory(memory_, [this, owner = std::move(owner)](
                                             boost::system::error_code ec, size_t n) {
                      writing_ = false;
                      write_timer_.cancel();
                      clear_write_buffer(write_buffer_);
                      if (ec) {
                        owner->on_closed();
                        return;
                      }
                      owner->on_written(n);
                    }));
}

void TcpConnection::close() {
  frame_timer_.cancel();
  write_timer_.cancel();
  if (!socket_.is_open()) return;
  boost::system::error_code ignored;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  socket_.close(ignored);
}

}  // namespace vox::net
