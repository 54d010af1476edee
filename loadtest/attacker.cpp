#include "loadtest/attacker.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <cmath>
#include <limits>

#include "loadtest/load_test.hpp"

namespace vox::loadtest {

namespace asio = boost::asio;

namespace {
constexpr double kFloodEveryS = 0.02;
constexpr double kHeavyEveryS = 0.02;  // refill the edit window at most this often
constexpr double kSlowCheckEveryS = 1;
constexpr double kSlowPingEveryS = 5;  // keeps the idle timer quiet; a failed ping shows the close
constexpr double kSquatPingEveryS = 10;
constexpr double kReconnectPauseS = 0.2;  // +-50%; a refused attacker must not spin a core
constexpr float kFarPlace = 100000;       // voxels from the origin, on x and z
constexpr float kFarDepth = 3000;         // |y| of a flooder's view off the surface
constexpr size_t kMaxOutboxBytes = 64 * 1024;
constexpr size_t kMaxServerFrame = 16 << 20;  // docs/PROTOCOL.md 4.1: accept at least 16 MiB
constexpr int kSlowReceiveBuffer = 4096;
// Fallbacks for a Welcome without limits (an older server).
constexpr uint32_t kDefaultViewRadius = 12, kDefaultInFlight = 256;
constexpr float kDefaultEditRadius = 16;

// Empty frames in one write: a 4-byte zero length each.
constexpr size_t kEmptyFramesPerWrite = 4096;
const std::vector<uint8_t>& empty_frames() {
  static const std::vector<uint8_t> frames(kEmptyFramesPerWrite * proto::kFrameHeaderBytes, 0);
  return frames;
}

bool closes_connection(int code) {
  return code != wire::Error::BAD_VALUE && code != wire::Error::UNKNOWN_MESSAGE &&
         code != wire::Error::DUPLICATE_HELLO && code != wire::Error::UNKNOWN_ENUM;
}
}  // namespace

Attacker::Attacker(LoadTest& test, AttackKind kind, int index, uint32_t seed)
    : test_(test),
      tally_(test.attack_tally()),
      kind_(kind),
      index_(index),
      rng_(seed),
      strand_(asio::make_strand(test.io())),
      socket_(strand_),
      timer_(strand_),
      decoder_(kMaxServerFrame) {
  spot_ = test.random_player_position(rng_);
}

double Attacker::now_s() const { return test_.now_s(); }

bool Attacker::silent() const {
  return kind_ == AttackKind::squat && index_ % kSquatGroupSize < kSquatGroupSize / 2;
}

void Attacker::start() {
  asio::dispatch(strand_, [self = shared_from_this()] { self->connect(); });
}

void Attacker::stop() {
  asio::dispatch(strand_, [self = shared_from_this()] {
    self->stopped_ = true;
    ++self->connection_;
    self->timer_.cancel();
    boost::system::error_code ignored;
    self->socket_.close(ignored);
  });
}

void Attacker::connect() {
  if (stopped_) return;
  const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(test_.config().host),
                                         test_.config().port);
  boost::system::error_code ec;
  socket_.open(endpoint.protocol(), ec);
  if (ec) {
    tally_.count(kind_, AttackTally::kConnectFailures);
    lost(false, kReconnectPauseS);
    return;
  }
  if (test_.config().spread_addresses) {
    // One address per hostile client: a squatter's sockets share theirs.
    const int client = kind_ == AttackKind::squat ? index_ / kSquatGroupSize : index_;
    socket_.bind(
        {asio::ip::make_address(spread_source_address(1 + static_cast<int>(kind_), client)), 0},
        ec);
    if (ec) {
      tally_.count(kind_, AttackTally::kConnectFailures);
      lost(false, kReconnectPauseS);
      return;
    }
  }
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);
  // Before connecting, so the window the server sees is small from the start.
  if (kind_ == AttackKind::slow)
    socket_.set_option(asio::socket_base::receive_buffer_size(kSlowReceiveBuffer), ec);
  socket_.async_connect(
      endpoint, [self = shared_from_this(), c = connection_](boost::system::error_code error) {
        if (self->stopped_ || c != self->connection_) return;
        if (error) {
          self->tally_.count(self->kind_, AttackTally::kConnectFailures);
          self->lost(false, kReconnectPauseS);
          return;
        }
        self->on_connected();
      });
}

void Attacker::on_connected() {
  open_ = true;
  welcomed_ = false;
  in_flight_ = 0;
  decoder_ = proto::FrameDecoder(kMaxServerFrame);
  tally_.count(kind_, AttackTally::kConnects);
  if (!silent()) {
    wire::Envelope hello;
    hello.mutable_hello()->set_protocol_version(1);
    hello.mutable_hello()->set_player_name(std::string(attack_kind_name(kind_)) +
                                           std::to_string(index_));
    send(hello);
  }
  read_more();
}

void Attacker::lost(bool by_server, double pause_s) {
  if (stopped_) return;
  if (by_server) tally_.count(kind_, AttackTally::kDisconnects);
  ++connection_;
  open_ = welcomed_ = writing_ = false;
  outbox_.clear();
  boost::system::error_code ignored;
  socket_.close(ignored);
  std::uniform_real_distribution<double> jitter(0.5, 1.5);
  arm_timer(pause_s * jitter(rng_));
}

void Attacker::arm_timer(double seconds) {
  timer_.expires_after(std::chrono::microseconds(static_cast<int64_t>(seconds * 1e6)));
  timer_.async_wait([self = shared_from_this(), c = connection_](boost::system::error_code ec) {
    if (!ec && !self->stopped_ && c == self->connection_) self->on_timer();
  });
}

void Attacker::on_timer() {
  if (!open_) return connect();  // the pause after a close is over
  switch (kind_) {
    case AttackKind::flood:
      return flood_step();
    case AttackKind::heavy:
      return heavy_step();
    case AttackKind::squat:
      return squat_step();
    case AttackKind::slow:
      return slow_step();
    case AttackKind::empty:
      return;  // driven by its writes, not by the timer
  }
}

void Attacker::read_more() {
  socket_.async_read_some(asio::buffer(buffer_), [self = shared_from_this(), c = connection_](
                                                     boost::system::error_code ec, size_t n) {
    if (self->stopped_ || c != self->connection_) return;
    if (ec) return self->lost(true, kReconnectPauseS);
    self->tally_.count(self->kind_, AttackTally::kBytesReceived, n);
    self->decoder_.feed({self->buffer_.data(), n});
    while (auto frame = self->decoder_.next()) {
      self->on_frame(*frame);
      if (c != self->connection_) return;  // on_frame closed the connection
    }
    if (!self->decoder_.error().empty()) return self->lost(true, kReconnectPauseS);
    // A slow reader stops here for good: what the server sends next piles up.
    if (self->kind_ == AttackKind::slow && self->welcomed_) return;
    self->read_more();
  });
}

void Attacker::on_frame(std::span<const uint8_t> body) {
  wire::Envelope m;
  if (!m.ParseFromArray(body.data(), static_cast<int>(body.size()))) return;
  tally_.count(kind_, AttackTally::kMessagesReceived);
  switch (m.body_case()) {
    case wire::Envelope::kWelcome:
      on_welcome(m.welcome());
      break;
    case wire::Envelope::kEditResult:
      tally_.edit_result(kind_, m.edit_result().status());
      if (in_flight_ > 0) --in_flight_;
      break;
    case wire::Envelope::kError:
      tally_.error(kind_, m.error().code());
      // The server closes after these: go now rather than wait to read the close.
      if (closes_connection(m.error().code())) lost(true, kReconnectPauseS);
      break;
    default:
      break;  // meshes, unloads, pongs: received and dropped
  }
}

void Attacker::on_welcome(const wire::Welcome& w) {
  if (welcomed_) return;
  welcomed_ = true;
  tally_.count(kind_, AttackTally::kWelcomed);
  tally_.set_server_limits({{"max_view_radius", w.max_view_radius()},
                            {"max_edits_in_flight", w.max_edits_in_flight()},
                            {"max_edit_radius", w.max_edit_radius()},
                            {"max_frame_bytes", w.max_frame_bytes()},
                            {"edit_budget_per_second", w.edit_budget_per_second()},
                            {"edit_budget_burst", w.edit_budget_burst()},
                            {"max_set_views_per_second", w.max_set_views_per_second()},
                            {"max_connections_per_address", w.max_connections_per_address()}});
  max_view_radius_ = w.max_view_radius() > 0 ? w.max_view_radius() : kDefaultViewRadius;
  max_in_flight_ = w.max_edits_in_flight() > 0 ? w.max_edits_in_flight() : kDefaultInFlight;
  max_edit_radius_ = w.max_edit_radius() > 0 ? w.max_edit_radius() : kDefaultEditRadius;
  switch (kind_) {
    case AttackKind::flood:
      leave_at_s_ = index_ % 2 == 0 ? now_s() + std::uniform_real_distribution<double>(2, 5)(rng_)
                                    : std::numeric_limits<double>::infinity();
      return flood_step();
    case AttackKind::heavy:
      return heavy_step();
    case AttackKind::squat:
      return arm_timer(kSquatPingEveryS);
    case AttackKind::slow: {
      auto at = test_.random_player_position(rng_);
      at[1] = test_.terrain_height(at[0], at[2]);
      send(view_at(at));
      next_ping_s_ = now_s() + kSlowPingEveryS;
      return arm_timer(kSlowCheckEveryS);
    }
    case AttackKind::empty:
      return write_more();  // starts the empty frames once the Hello is out
  }
}

bool Attacker::send(const wire::Envelope& m) {
  if (!open_) return false;
  const std::string body = m.SerializeAsString();
  if (outbox_.size() + proto::kFrameHeaderBytes + body.size() > kMaxOutboxBytes) {
    tally_.count(kind_, AttackTally::kSendsDropped);
    return false;
  }
  proto::append_frame({reinterpret_cast<const uint8_t*>(body.data()), body.size()}, outbox_);
  tally_.count(kind_, AttackTally::kMessagesSent);
  write_more();
  return true;
}

void Attacker::write_more() {
  if (writing_ || !open_) return;
  if (outbox_.empty()) {
    if (kind_ == AttackKind::empty && welcomed_) write_empty_frames();
    return;
  }
  writing_ = true;
  in_write_.clear();
  std::swap(outbox_, in_write_);
  asio::async_write(
      socket_, asio::buffer(in_write_),
      [self = shared_from_this(), c = connection_](boost::system::error_code ec, size_t) {
        if (self->stopped_ || c != self->connection_) return;
        self->writing_ = false;
        if (ec) return self->lost(true, kReconnectPauseS);
        self->write_more();
      });
}

void Attacker::write_empty_frames() {
  writing_ = true;
  asio::async_write(
      socket_, asio::buffer(empty_frames()),
      [self = shared_from_this(), c = connection_](boost::system::error_code ec, size_t) {
        if (self->stopped_ || c != self->connection_) return;
        self->writing_ = false;
        if (ec) return self->lost(true, kReconnectPauseS);
        self->tally_.count(self->kind_, AttackTally::kMessagesSent, kEmptyFramesPerWrite);
        self->write_more();
      });
}

std::array<float, 3> Attacker::far_place() {
  std::uniform_real_distribution<float> across(-kFarPlace, kFarPlace);
  const float x = std::round(across(rng_)), z = std::round(across(rng_));
  return {x, test_.terrain_height(x, z), z};
}

wire::Envelope Attacker::view_at(const std::array<float, 3>& at) const {
  wire::Envelope v;
  auto* view = v.mutable_set_view();
  view->mutable_position()->set_x(at[0]);
  view->mutable_position()->set_y(at[1]);
  view->mutable_position()->set_z(at[2]);
  view->set_radius(max_view_radius_);
  return v;
}

void Attacker::flood_step() {
  if (now_s() >= leave_at_s_) return lost(false, 0);  // burst over: a fresh connection at once
  auto at = far_place();
  // Half the views off the surface, where the chunks are solid or air and cheap to send
  // but still have to be generated.
  if (std::uniform_int_distribution<int>(0, 1)(rng_) == 1)
    at[1] = std::round(std::uniform_real_distribution<float>(-kFarDepth, kFarDepth)(rng_));
  send(view_at(at));
  arm_timer(kFloodEveryS);
}

// A box of side exactly 2*max_edit_radius: integral centre and half side keep the float
// corners exact, so rounding never makes it a BAD_RADIUS.
wire::Envelope Attacker::heavy_stamp() {
  std::array<float, 3> c = far_place();
  if (std::uniform_int_distribution<int>(0, 3)(rng_) == 0) {
    c = {std::round(spot_[0]), 0, std::round(spot_[2])};
    c[1] = test_.terrain_height(c[0], c[2]);
  }
  c[1] = std::round(c[1]);
  const float half = max_edit_radius_ >= 1 ? std::floor(max_edit_radius_) : max_edit_radius_;
  wire::Envelope m;
  auto* e = m.mutable_edit();
  e->set_request_id(next_request_++);
  auto* s = e->mutable_stamp();
  s->set_shape(wire::Stamp::BOX);
  s->mutable_min()->set_x(c[0] - half);
  s->mutable_min()->set_y(c[1] - half);
  s->mutable_min()->set_z(c[2] - half);
  s->mutable_max()->set_x(c[0] + half);
  s->mutable_max()->set_y(c[1] + half);
  s->mutable_max()->set_z(c[2] + half);
  s->set_solid(std::uniform_int_distribution<int>(0, 1)(rng_) == 1);
  s->set_material(static_cast<uint32_t>(std::uniform_int_distribution<int>(1, 4)(rng_)));
  return m;
}

void Attacker::heavy_step() {
  while (in_flight_ < max_in_flight_ && open_) {
    if (!send(heavy_stamp())) break;  // the outbox is full: the socket is the limit
    ++in_flight_;
    tally_.count(kind_, AttackTally::kEditsSent);
  }
  if (open_) arm_timer(kHeavyEveryS);
}

void Attacker::squat_step() {
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(static_cast<uint64_t>(now_s() * 1000));
  send(ping);
  arm_timer(kSquatPingEveryS);
}

// The slow reader does not read, so it cannot see the server's close as an end of file:
// the socket's TCP state shows a FIN or a reset, and a ping to a closed socket fails.
void Attacker::slow_step() {
  tcp_info info{};
  socklen_t size = sizeof info;
  if (::getsockopt(socket_.native_handle(), IPPROTO_TCP, TCP_INFO, &info, &size) == 0 &&
      info.tcpi_state != TCP_ESTABLISHED) {
    return lost(true, kReconnectPauseS);
  }
  if (now_s() >= next_ping_s_) {
    wire::Envelope ping;
    ping.mutable_ping()->set_nonce(static_cast<uint64_t>(now_s() * 1000));
    send(ping);
    next_ping_s_ = now_s() + kSlowPingEveryS;
  }
  arm_timer(kSlowCheckEveryS);
}

}  // namespace vox::loadtest
