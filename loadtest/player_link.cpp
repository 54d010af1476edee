// TCP: each Envelope a length-prefixed frame (proto/framing.hpp).
#include "loadtest/player_link.hpp"

#include <array>
#include <vector>

#include "proto/framing.hpp"

namespace vox::loadtest {

namespace asio = boost::asio;

namespace {

class TcpLink final : public PlayerLink {
 public:
  TcpLink(PlayerStrand strand, LinkTarget target)
      : target_(std::move(target)), socket_(std::move(strand)) {}

  void connect(Done done) override {
    const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(target_.host), target_.port);
    if (std::string error = bind_source(socket_, endpoint, target_.source); !error.empty()) {
      done(error);
      return;
    }
    socket_.async_connect(endpoint, [this, done = std::move(done)](boost::system::error_code ec) {
      if (ec) {
        done("connect failed: " + ec.message());
        return;
      }
      boost::system::error_code ignored;
      socket_.set_option(asio::ip::tcp::no_delay(true), ignored);
      done({});
    });
  }

  void write(std::span<const uint8_t> envelope, Done done) override {
    const auto size = static_cast<uint32_t>(envelope.size());
    for (size_t i = 0; i < header_.size(); ++i) header_[i] = static_cast<uint8_t>(size >> (8 * i));
    const std::array<asio::const_buffer, 2> frame{asio::buffer(header_),
                                                  asio::buffer(envelope.data(), envelope.size())};
    asio::async_write(socket_, frame,
                      [done = std::move(done)](boost::system::error_code ec, size_t) {
                        done(ec ? "write failed: " + ec.message() : std::string());
                      });
  }

  void read(Read done) override {
    socket_.async_read_some(asio::buffer(buffer_),
                            [this, done = std::move(done)](boost::system::error_code ec, size_t n) {
                              if (ec) {
                                done("closed by the server", 0);
                                return;
                              }
                              decoder_.feed({buffer_.data(), n});
                              done({}, n);
                            });
  }

  std::optional<std::span<const uint8_t>> next_message() override {
    auto frame = decoder_.next();
    if (!frame) return std::nullopt;
    current_ = std::move(*frame);
    return std::span<const uint8_t>(current_);
  }

  const std::string& message_error() const override {
    static const std::string kTooLarge = "frame over the limit from the server";
    static const std::string kNone;
    return decoder_.error().empty() ? kNone : kTooLarge;
  }

  void close() override {
    boost::system::error_code ignored;
    socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
  }

 private:
  LinkTarget target_;
  asio::ip::tcp::socket socket_;
  std::array<uint8_t, proto::kFrameHeaderBytes> header_{};
  std::array<uint8_t, 64 * 1024> buffer_;
  proto::FrameDecoder decoder_{64 << 20};
  std::vector<uint8_t> current_;
};

}  // namespace

std::unique_ptr<PlayerLink> make_tcp_link(PlayerStrand strand, LinkTarget target) {
  return std::make_unique<TcpLink>(std::move(strand), std::move(target));
}

size_t ws_server_frame_bytes(size_t payload) {
  return payload + (payload < 126 ? 2 : payload < 65536 ? 4 : 10);
}

}  // namespace vox::loadtest
