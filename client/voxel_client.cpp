#include "client/voxel_client.hpp"

#include <stdexcept>

namespace vox::client {

namespace asio = boost::asio;

Client::Client() : socket_(io_) {}
Client::~Client() {
  boost::system::error_code ignored;
  socket_.close(ignored);
}

void Client::connect(const std::string& host, uint16_t port, std::chrono::milliseconds timeout) {
  asio::ip::tcp::resolver resolver(io_);
  boost::system::error_code ec;
  const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
  if (ec) throw std::runtime_error("cannot resolve " + host + ": " + ec.message());
  bool done = false;
  asio::async_connect(socket_, endpoints,
                      [&](boost::system::error_code e, const asio::ip::tcp::endpoint&) {
                        ec = e;
                        done = true;
                      });
  io_.restart();
  io_.run_for(timeout);
  if (!done) {
    socket_.close(ec);
    throw std::runtime_error("cannot connect to " + host + ":" + std::to_string(port) +
                             ": timed out");
  }
  if (ec)
    throw std::runtime_error("cannot connect to " + host + ":" + std::to_string(port) + ": " +
                             ec.message());
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);
}

wire::Welcome Client::handshake(const std::string& name, std::chrono::milliseconds timeout,
                                const std::string& token) {
  send(make_hello(name, 1, token));
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    auto m =
        receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!m) break;
    if (m->has_welcome()) return m->welcome();
    if (m->has_error()) throw std::runtime_error("server refused: " + m->error().message());
  }
  throw std::runtime_error(closed_ ? "server closed the connection during the handshake"
                                   : "no Welcome in time");
}

void Client::send(const wire::Envelope& message) {
  std::vector<uint8_t> frame;
  const std::string body = message.SerializeAsString();
  proto::append_frame({reinterpret_cast<const uint8_t*>(body.data()), body.size()}, frame);
  send_raw(frame);
}

void Client::send_raw(std::span<const uint8_t> bytes) {
  boost::system::error_code ec;
  asio::write(socket_, asio::buffer(bytes.data(), bytes.size()), ec);
  if (ec) closed_ = true;
}

std::optional<wire::Envelope> Client::receive(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    if (auto frame = decoder_.next()) {
      wire::Envelope m;
      if (!m.ParseFromArray(frame->data(), static_cast<int>(frame->size()))) {
        closed_ = true;
        return std::nullopt;
      }
      return m;
    }
    if (closed_ || Clock::now() >= deadline) return std::nullopt;
    bool done = false;
    socket_.async_read_some(asio::buffer(buffer_), [&](boost::system::error_code ec, size_t n) {
      done = true;
      if (ec == asio::error::operation_aborted) return;  // our own deadline
      if (ec) {
        closed_ = true;
        return;
      }
      decoder_.feed({buffer_.data(), n});
    });
    io_.restart();
    io_.run_until(deadline);
    if (!done) {  // deadline: cancel the read and let its handler run
      socket_.cancel();
      io_.restart();
      io_.run();
      return std::nullopt;
    }
  }
}

// A level the protocol can carry (a chunk of 32 * 2^level voxels in 32-bit coordinates).
constexpr uint32_t kMaxLevel = 26;

std::optional<std::string> Client::apply(const wire::ChunkMesh& m) {
  if (m.level() == 0) return cache_.apply(m, zstd_, scratch_, decoded_);
  if (m.level() > kMaxLevel) return "a chunk of level " + std::to_string(m.level());
  return lod_cache_[m.level()].apply(m, zstd_, scratch_, decoded_);
}

void Client::forget(const wire::ChunkUnload& u) {
  if (u.level() == 0) {
    cache_.forget(u);
  } else if (auto it = lod_cache_.find(u.level()); it != lod_cache_.end()) {
    it->second.forget(u);
  }
}

const HeldChunks& Client::lod_chunks(uint32_t level) const {
  static const HeldChunks kNone;
  const auto it = lod_cache_.find(level);
  return it == lod_cache_.end() ? kNone : it->second.chunks();
}

wire::ViewReady Client::receive_view(uint64_t view_id, std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    auto m =
        receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!m) break;
    if (m->has_error()) throw std::runtime_error("server error: " + m->error().message());
    if (m->has_chunk_unload()) forget(m->chunk_unload());
    if (m->has_chunk_mesh()) {
      if (auto error = apply(m->chunk_mesh()))
        throw std::runtime_error("bad mesh from the server: " + *error);
    }
    if (m->has_view_ready() && m->view_ready().view_id() == view_id) return m->view_ready();
  }
  throw std::runtime_error(closed_ ? "the server closed the connection before the view was complete"
                                   : "the view was not complete in time");
}

wire::Envelope make_hello(const std::string& name, uint32_t version, const std::string& token) {
  wire::Envelope m;
  m.mutable_hello()->set_protocol_version(version);
  m.mutable_hello()->set_player_name(name);
  if (!token.empty()) m.mutable_hello()->set_token(token);
  return m;
}

wire::Envelope make_set_view(float x, float y, float z, uint32_t radius, uint64_t view_id,
                             uint32_t lod_level, float lod_distance) {
  wire::Envelope m;
  auto* v = m.mutable_set_view();
  v->set_lod_level(lod_level);
  v->set_lod_distance(lod_distance);
  v->set_view_id(view_id);
  v->mutable_position()->set_x(x);
  v->mutable_position()->set_y(y);
  v->mutable_position()->set_z(z);
  v->set_radius(radius);
  return m;
}

wire::Envelope make_resync(std::span<const wire::ChunkCoord> coords, uint32_t level) {
  wire::Envelope m;
  m.mutable_resync()->set_level(level);
  for (const auto& c : coords) *m.mutable_resync()->add_coords() = c;
  return m;
}

wire::Envelope make_brush(uint64_t request_id, float x, float y, float z, float radius,
                          float strength, bool remove) {
  wire::Envelope m;
  auto* e = m.mutable_edit();
  e->set_request_id(request_id);
  auto* b = e->mutable_brush();
  b->mutable_center()->set_x(x);
  b->mutable_center()->set_y(y);
  b->mutable_center()->set_z(z);
  b->set_radius(radius);
  b->set_strength(strength);
  b->set_remove(remove);
  return m;
}

}  // namespace vox::client
