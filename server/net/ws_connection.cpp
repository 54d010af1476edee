#include "server/net/ws_connection.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <algorithm>

namespace vox::net {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using Clock = std::chrono::steady_clock;

namespace {

// Bytes one read takes from the socket (a message may take several).
constexpr size_t kReadChunk = 16 * 1024;
// A close frame that does not go out in this time: the socket is closed anyway.
constexpr auto kCloseGrace = std::chrono::seconds(1);

// Corks the socket while a write's messages go out one Beast write each, so that the
// kernel sends them as full segments at the uncork instead of pushing each message
// through the network path alone (the TCP transport writes them in one call).
void cork(WsStream& ws, bool on) {
  const int value = on ? 1 : 0;
  ::setsockopt(beast::get_lowest_layer(ws).socket().native_handle(), IPPROTO_TCP, TCP_CORK, &value,
               sizeof value);
}

void close_socket(WsStream& ws) {
  boost::system::error_code ignored;
  auto& socket = beast::get_lowest_layer(ws).socket();
  if (!socket.is_open()) return;
  socket.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  socket.close(ignored);
}

}  // namespace

struct WsConnection::State {
  State(WsStream s, std::chrono::milliseconds timeout, ServerCounters& c)
      : ws(std::move(s)),
        strand(ws.get_executor()),
        frame_timer(strand),
        write_timer(strand),
        close_timer(strand),
        frame_timeout(timeout),
        counters(c),
        ping_tokens(kMaxPingsPerSecond),
        ping_at(Clock::now()) {}

  HandlerMemory::Owner memory = HandlerMemory::make();  // for the operations below
  WsStream ws;
  Strand strand;  // the stream's executor
  StrandTimer frame_timer, write_timer, close_timer;
  const std::chrono::milliseconds frame_timeout;
  ServerCounters& counters;
  beast::flat_buffer message;  // the message being received (whole once message_ready)
  bool message_ready = false;
  bool reading = false;
  // When the message being received started (none: none has started).
  std::optional<Clock::time_point> partial_since;
  bool frame_watch = false;
  std::vector<uint8_t> write_buffer;  // the next write's messages, back to back
  std::vector<size_t> message_ends;   // where each of them ends in write_buffer
  bool writing = false;
  bool corked = false;     // the write in flight corked the socket
  uint64_t write_seq = 0;  // of the write in flight: a late deadline of an earlier one is ignored
  bool closed = false;     // close() was called
  std::optional<websocket::close_code> close_code;
  std::weak_ptr<Connection::Events> reader;  // the session reading (the ping flood's)
  double ping_tokens;
  Clock::time_point ping_at;
  bool ping_flood = false;
};

// Too many pings: counted once, and the session closes with policy violation.
void WsConnection::ping_flood(State& s, Events& owner) {
  if (s.close_code) return;  // told already
  ServerCounters::bump(s.counters.ws_closed[static_cast<size_t>(WsClosedBy::kPingFlood)]);
  s.close_code = websocket::close_code::policy_error;
  owner.on_closed();
}

WsConnection::WsConnection(WsStream ws, size_t max_frame_bytes,
                           std::chrono::milliseconds frame_timeout, ServerCounters& counters)
    : state_(std::make_shared<State>(std::move(ws), frame_timeout, counters)) {
  State& s = *state_;
  s.ws.binary(true);
  s.ws.auto_fragment(false);
  s.ws.read_message_max(max_frame_bytes);
  beast::get_lowest_layer(s.ws).expires_never();  // the stream's own timeouts below
  websocket::stream_base::timeout timeouts{};
  timeouts.handshake_timeout = kCloseGrace;                // the closing handshake
  timeouts.idle_timeout = websocket::stream_base::none();  // the session's idle timer
  timeouts.keep_alive_pings = false;
  s.ws.set_option(timeouts);
  // Pings are answered by the stream; past the rate the connection is closed (a flood of
  // them costs the server pongs while the session sees no message to count).
  s.ws.control_callback([weak = std::weak_ptr<State>(state_)](websocket::frame_type kind,
                                                              beast::string_view) {
    const std::shared_ptr<State> st = weak.lock();
    if (!st) return;
    if (kind != websocket::frame_type::ping || st->ping_flood) return;
    const Clock::time_point now = Clock::now();
    st->ping_tokens =
        std::min(kMaxPingsPerSecond,
                 st->ping_tokens +
                     kMaxPingsPerSecond * std::chrono::duration<double>(now - st->ping_at).count());
    st->ping_at = now;
    if ((st->ping_tokens -= 1) >= 0) return;
    st->ping_flood = true;
    // The stream answers the pings and reads on: its session is told after this handler.
    asio::post(st->ws.get_executor(), [st] {
      if (auto owner = st->reader.lock()) ping_flood(*st, *owner);
    });
  });
}

WsConnection::~WsConnection() {
  // Not closed by the session (it ended with the io_context): nothing more goes out.
  if (!state_->closed) close_socket(state_->ws);
}

Strand& WsConnection::strand() { return state_->strand; }

bool WsConnection::open() const {
  return !state_->closed && beast::get_lowest_layer(state_->ws).socket().is_open();
}

bool WsConnection::writing() const { return state_->writing; }

size_t WsConnection::pending_bytes() const { return state_->write_buffer.size(); }

size_t WsConnection::memory_bytes() const {
  const State& s = *state_;
  return s.write_buffer.capacity() + s.message_ends.capacity() * sizeof(size_t) +
         s.message.capacity() + kReadChunk + HandlerMemory::bytes();
}

size_t WsConnection::bytes_buffered() const {
  return state_->message_ready ? 0 : state_->message.size();
}

// The message already received first (after a pause), then more.
void WsConnection::read(std::shared_ptr<Events> owner) {
  State& s = *state_;
  if (s.message_ready) {
    s.message_ready = false;
    const auto data = s.message.cdata();
    const bool go_on = owner->on_message({static_cast<const uint8_t*>(data.data()), data.size()});
    s.message.consume(s.message.size());
    if (!go_on || !open()) return;
  }
  watch_partial_message(owner);
  read_some(std::move(owner));
}

void WsConnection::read_some(std::shared_ptr<Events> owner) {
  State& s = *state_;
  if (s.reading || !open()) return;
  s.reading = true;
  s.reader = owner;
  s.ws.async_read_some(
      s.message, kReadChunk,
      with_memory(s.memory, [this, owner = std::move(owner)](boost::system::error_code ec,
                                                             size_t) mutable {
        State& s = *state_;
        s.reading = false;
        if (s.ping_flood) {
          ping_flood(s, *owner);
          return;
        }
        if (ec == websocket::error::message_too_big) {
          stream_error(owner, wire::Error::FRAME_TOO_LARGE, websocket::close_code::too_big,
                       "a message over the frame limit (Welcome.max_frame_bytes)");
          return;
        }
        if (ec) {
          // The peer broke the WebSocket protocol (the stream closed with 1002): counted.
          if (ec.category() == websocket::make_error_code(websocket::error::closed).category() &&
              ec != websocket::error::closed)
            ServerCounters::bump(s.counters.ws_closed[static_cast<size_t>(WsClosedBy::kProtocol)]);
          owner->on_closed();
          return;
        }
        if (!s.ws.is_message_done()) {
          if (!s.partial_since) s.partial_since = Clock::now();
          read(std::move(owner));
          return;
        }
        s.partial_since.reset();
        if (s.ws.got_text()) {
          stream_error(owner, wire::Error::MALFORMED, websocket::close_code::unknown_data,
                       "a text message: every message is one binary Envelope");
          return;
        }
        s.message_ready = true;
        read(std::move(owner));
      }));
}

void WsConnection::stream_error(const std::shared_ptr<Events>& owner, wire::Error::Code code,
                                websocket::close_code close, const std::string& why) {
  State& s = *state_;
  ServerCounters::bump(s.counters.ws_closed[static_cast<size_t>(
      close == websocket::close_code::too_big        ? WsClosedBy::kTooBig
      : close == websocket::close_code::unknown_data ? WsClosedBy::kText
                                                     : WsClosedBy::kFrameTimeout)]);
  s.close_code = close;
  owner->on_stream_error(code, why);
}

void WsConnection::watch_partial_message(std::shared_ptr<Events> owner) {
  State& s = *state_;
  if (!s.partial_since || s.frame_watch) return;
  s.frame_watch = true;
  s.frame_timer.expires_at(*s.partial_since + s.frame_timeout);
  s.frame_timer.async_wait(
      with_memory(s.memory, [this, owner = std::move(owner)](boost::system::error_code ec) mutable {
        State& s = *state_;
        s.frame_watch = false;
        if (ec || !open() || !s.partial_since) return;
        if (Clock::now() >= *s.partial_since + s.frame_timeout) {
          stream_error(owner, wire::Error::FRAME_TIMEOUT, websocket::close_code::policy_error,
                       "a message was not completed within the frame timeout");
          return;
        }
        watch_partial_message(std::move(owner));  // a later message is partial now: watch it
      }));
}

void WsConnection::append(const google::protobuf::MessageLite& message) {
  State& s = *state_;
  const size_t size = message.ByteSizeLong();
  const size_t at = s.write_buffer.size();
  s.write_buffer.resize(at + size);
  message.SerializeWithCachedSizesToArray(s.write_buffer.data() + at);
  s.message_ends.push_back(s.write_buffer.size());
}

void WsConnection::append_serialized(std::span<const uint8_t> body) {
  State& s = *state_;
  s.write_buffer.insert(s.write_buffer.end(), body.begin(), body.end());
  s.message_ends.push_back(s.write_buffer.size());
}

void WsConnection::write(std::shared_ptr<Events> owner, std::chrono::milliseconds deadline) {
  State& s = *state_;
  if (s.writing || s.message_ends.empty() || !open()) return;
  s.writing = true;
  const uint64_t seq = ++s.write_seq;
  if (deadline.count() > 0) {
    s.write_timer.expires_after(deadline);
    s.write_timer.async_wait(
        with_memory(s.memory, [this, owner, seq](boost::system::error_code ec) {
          if (!ec && state_->writing && state_->write_seq == seq) owner->on_write_timeout();
        }));
  }
  s.corked = s.message_ends.size() > 1;
  if (s.corked) cork(s.ws, true);
  write_next(std::move(owner), 0, 0);
}

// Message `index` of the write, each its own binary message, in order.
void WsConnection::write_next(std::shared_ptr<Events> owner, size_t index, size_t written) {
  State& s = *state_;
  const size_t begin = index == 0 ? 0 : s.message_ends[index - 1];
  const size_t end = s.message_ends[index];
  s.ws.async_write(asio::buffer(s.write_buffer.data() + begin, end - begin),
                   with_memory(s.memory, [this, owner = std::move(owner), index, written](
                                             boost::system::error_code ec, size_t n) mutable {
                     State& s = *state_;
                     if (!ec && index + 1 < s.message_ends.size()) {
                       write_next(std::move(owner), index + 1, written + n);
                       return;
                     }
                     s.writing = false;
                     s.write_timer.cancel();
                     if (s.corked) cork(s.ws, false);
                     s.corked = false;
                     clear_write_buffer(s.write_buffer);
                     s.message_ends.clear();
                     if (ec) {
                       owner->on_closed();
                       return;
                     }
                     owner->on_written(written + n);
                   }));
}

void WsConnection::close() {
  std::shared_ptr<State> st = state_;
  if (st->closed) return;
  st->closed = true;
  st->frame_timer.cancel();
  st->write_timer.cancel();
  // A close frame cannot go out behind a write in flight, nor on a stream already closed.
  if (st->writing || !st->ws.is_open()) {
    close_socket(st->ws);
    return;
  }
  st->close_timer.expires_after(kCloseGrace);
  st->close_timer.async_wait([st](boost::system::error_code ec) {
    if (!ec) close_socket(st->ws);
  });
  st->ws.async_close(st->close_code.value_or(websocket::close_code::going_away),
                     [st](boost::system::error_code) {
                       st->close_timer.cancel();
                       close_socket(st->ws);
                     });
}

}  // namespace vox::net
