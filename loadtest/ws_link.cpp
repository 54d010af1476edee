// WebSocket: GET /ws on voxeld's HTTP port, then each Envelope one binary message with no
// length prefix (docs/PROTOCOL.md 4.1). Beast's stream gets the player's strand as its
// executor, so its handlers (and its internal ones: pongs, the close) run there.
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include "loadtest/player_link.hpp"

namespace vox::loadtest {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;

namespace {

class WsLink final : public PlayerLink {
 public:
  WsLink(PlayerStrand strand, LinkTarget target)
      : target_(std::move(target)), ws_(std::move(strand)) {
    ws_.binary(true);
    ws_.auto_fragment(false);
    ws_.read_message_max(64 << 20);  // as the TCP link's frame limit
  }

  void connect(Done done) override {
    const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(target_.host), target_.port);
    auto& socket = beast::get_lowest_layer(ws_).socket();
    if (std::string error = bind_source(socket, endpoint, target_.source); !error.empty()) {
      done(error);
      return;
    }
    beast::get_lowest_layer(ws_).async_connect(
        endpoint, [this, done = std::move(done)](beast::error_code ec) mutable {
          if (ec) {
            done("connect failed: " + ec.message());
            return;
          }
          boost::system::error_code ignored;
          beast::get_lowest_layer(ws_).socket().set_option(asio::ip::tcp::no_delay(true), ignored);
          const std::string host = target_.host + ":" + std::to_string(target_.port);
          ws_.async_handshake(host, "/ws", [done = std::move(done)](beast::error_code ec) {
            done(ec ? "WebSocket upgrade failed: " + ec.message() : std::string());
          });
        });
  }

  void write(std::span<const uint8_t> envelope, Done done) override {
    ws_.async_write(asio::buffer(envelope.data(), envelope.size()),
                    [done = std::move(done)](beast::error_code ec, size_t) {
                      done(ec ? "write failed: " + ec.message() : std::string());
                    });
  }

  void read(Read done) override {
    buffer_.consume(buffer_.size());
    has_message_ = false;
    ws_.async_read(buffer_, [this, done = std::move(done)](beast::error_code ec, size_t n) {
      if (ec) {
        done("closed by the server", 0);
        return;
      }
      if (!ws_.got_binary()) error_ = "a text message from the server";
      has_message_ = error_.empty();
      done({}, ws_server_frame_bytes(n));
    });
  }

  std::optional<std::span<const uint8_t>> next_message() override {
    if (!has_message_) return std::nullopt;
    has_message_ = false;
    const auto data = buffer_.cdata();
    return std::span<const uint8_t>(static_cast<const uint8_t*>(data.data()), data.size());
  }

  const std::string& message_error() const override { return error_; }

  void close() override {
    boost::system::error_code ignored;
    beast::get_lowest_layer(ws_).socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    beast::get_lowest_layer(ws_).close();
  }

 private:
  LinkTarget target_;
  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
  bool has_message_ = false;
  std::string error_;
};

}  // namespace

std::unique_ptr<PlayerLink> make_ws_link(PlayerStrand strand, LinkTarget target) {
  return std::make_unique<WsLink>(std::move(strand), std::move(target));
}

}  // namespace vox::loadtest
