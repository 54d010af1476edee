#include "net/client_session.hpp"

#include <spdlog/spdlog.h>

#include <cmath>

#include "net/wire_convert.hpp"
#include "proto/mesh_codec.hpp"

namespace vox::net {

using world::ChunkCoord;

namespace {

// Appends the framed message to `out` (serialized in place, no temporary).
void append_framed(const wire::Envelope& message, std::vector<uint8_t>& out) {
  const size_t n = message.ByteSizeLong();
  const size_t at = out.size();
  out.resize(at + proto::kFrameHeaderBytes + n);
  for (size_t i = 0; i < proto::kFrameHeaderBytes; ++i)
    out[at + i] = static_cast<uint8_t>(n >> (8 * i));
  message.SerializeWithCachedSizesToArray(out.data() + at + proto::kFrameHeaderBytes);
}

std::vector<uint8_t> frame_of(const wire::Envelope& message) {
  std::vector<uint8_t> out;
  append_framed(message, out);
  return out;
}

bool finite(const wire::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

}  // namespace

ClientSession::ClientSession(asio::ip::tcp::socket socket, uint64_t id, const ServerConfig& config,
                             pipeline::WorldPipeline& pipeline, ServerCounters& counters)
    : socket_(std::move(socket)),
      strand_(asio::make_strand(socket_.get_executor())),
      handshake_timer_(strand_),
      idle_timer_(strand_),
      write_timer_(strand_),
      id_(id),
      config_(config),
      pipeline_(pipeline),
      counters_(counters),
      decoder_(config.max_frame_bytes) {}

ClientSession::~ClientSession() {
  if (player_) counters_.players.fetch_sub(1);
  pipeline_.drop_view(id_);
}

void ClientSession::start() {
  asio::dispatch(strand_, [self = shared_from_this()] {
    self->handshake_timer_.expires_after(self->config_.handshake_timeout);
    self->handshake_timer_.async_wait([self](boost::system::error_code ec) {
      if (!ec && !self->player_ && !self->closing_) {
        self->send_error(wire::Error::HANDSHAKE_TIMEOUT, "no Hello within the handshake timeout",
                         true);
      }
    });
    self->arm_idle_timer();
    self->read_more();
  });
}

void ClientSession::arm_idle_timer() {
  idle_timer_.expires_after(config_.idle_timeout);
  idle_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (!ec && !self->closing_)
      self->send_error(wire::Error::IDLE_TIMEOUT, "nothing received for too long", true);
  });
}

void ClientSession::read_more() {
  socket_.async_read_some(
      asio::buffer(read_buffer_),
      asio::bind_executor(strand_, [self = shared_from_this()](boost::system::error_code ec,
                                                               size_t n) {
        if (ec) {
          if (!self->closing_)
            spdlog::debug("session {}: connection closed by peer ({})", self->id_, ec.message());
          self->shutdown();
          return;
        }
        self->decoder_.feed({self->read_buffer_.data(), n});
        while (auto frame = self->decoder_.next()) {
          self->on_frame(*frame);
          if (self->closing_) return;
        }
        if (!self->decoder_.error().empty()) {
          self->send_error(wire::Error::FRAME_TOO_LARGE, self->decoder_.error(), true);
          return;
        }
        self->arm_idle_timer();
        self->read_more();
      }));
}

void ClientSession::on_frame(const std::vector<uint8_t>& body) {
  wire::Envelope message;
  if (!message.ParseFromArray(body.data(), static_cast<int>(body.size()))) {
    send_error(wire::Error::MALFORMED, "the frame is not a valid Envelope", true);
    return;
  }
  if (has_unknown_fields(message)) {
    send_error(wire::Error::UNKNOWN_MESSAGE,
               "the message has fields this protocol version does not define", false);
    return;
  }
  if (!player_ && message.body_case() != wire::Envelope::kHello) {
    send_error(wire::Error::NOT_HELLO, "the first message must be Hello", true);
    return;
  }
  switch (message.body_case()) {
    case wire::Envelope::kHello:
      handle_hello(message.hello());
      break;
    case wire::Envelope::kSetView:
      handle_set_view(message.set_view());
      break;
    case wire::Envelope::kEdit:
      handle_edit(message.edit());
      break;
    case wire::Envelope::kPing: {
      wire::Envelope pong;
      pong.mutable_pong()->set_nonce(message.ping().nonce());
      queue_control(pong);
      break;
    }
    default:
      send_error(wire::Error::UNKNOWN_MESSAGE, "not a client message", false);
  }
}

void ClientSession::handle_hello(const wire::Hello& hello) {
  if (player_) {
    send_error(wire::Error::DUPLICATE_HELLO, "Hello was already received", false);
    return;
  }
  if (hello.protocol_version() != kProtocolVersion) {
    send_error(wire::Error::BAD_VERSION,
               "protocol version " + std::to_string(hello.protocol_version()) +
                   " is not supported (server speaks " + std::to_string(kProtocolVersion) + ")",
               true);
    return;
  }
  if (hello.player_name().empty() || hello.player_name().size() > 32) {
    send_error(wire::Error::BAD_VALUE, "player_name must be 1..32 bytes", true);
    return;
  }
  name_ = hello.player_name();
  player_ = true;
  handshake_timer_.cancel();
  const uint64_t players = counters_.players.fetch_add(1) + 1;
  wire::Envelope welcome;
  auto* w = welcome.mutable_welcome();
  w->set_server_version(config_.server_version);
  w->set_world_seed(pipeline_.config().seed);
  w->set_chunk_size(world::kChunkSize);
  w->set_protocol_version(kProtocolVersion);
  w->set_max_view_radius(config_.max_view_radius);
  w->set_max_frame_bytes(static_cast<uint32_t>(config_.max_frame_bytes));
  w->set_max_edit_radius(pipeline_.config().limits.max_radius);
  w->set_max_edit_strength(pipeline_.config().limits.max_strength);
  w->set_mesh_format(proto::kMeshFormat);
  w->set_players(static_cast<uint32_t>(players));
  w->set_max_edits_in_flight(static_cast<uint32_t>(config_.max_edits_in_flight));
  queue_control(welcome);
  boost::system::error_code ec;
  const auto peer = socket_.remote_endpoint(ec);
  spdlog::info("session {}: player '{}' joined from {}", id_, name_,
               ec ? std::string("?") : peer.address().to_string());
}

void ClientSession::handle_set_view(const wire::SetView& view) {
  const auto& limits = pipeline_.config().limits;
  if (!finite(view.position())) {
    send_error(wire::Error::BAD_VALUE, "SetView position must be finite", false);
    return;
  }
  const float p[3] = {view.position().x(), view.position().y(), view.position().z()};
  for (int a = 0; a < 3; ++a) {
    if (p[a] < static_cast<float>(limits.world_min[a]) ||
        p[a] > static_cast<float>(limits.world_max[a])) {
      send_error(wire::Error::BAD_VALUE, "SetView position is outside the world", false);
      return;
    }
  }
  if (view.radius() > config_.max_view_radius) {
    send_error(wire::Error::BAD_VALUE,
               "view radius " + std::to_string(view.radius()) + " is over the limit of " +
                   std::to_string(config_.max_view_radius),
               false);
    return;
  }
  const int r = static_cast<int>(view.radius());
  const ChunkCoord center = world::chunk_of_voxel(static_cast<int32_t>(std::floor(p[0])),
                                                  static_cast<int32_t>(std::floor(p[1])),
                                                  static_cast<int32_t>(std::floor(p[2])));
  {
    std::lock_guard lock(view_mutex_);
    view_center_ = center;
    view_radius_ = r;
  }
  const std::vector<ChunkCoord> left = scheduler_.set_view(center, r);
  if (!left.empty()) {
    wire::Envelope unload;
    for (const ChunkCoord& c : left) *unload.mutable_chunk_unload()->add_coords() = to_wire(c);
    queue_control(unload);
  }
  // The pipeline loads what is missing (this view replaces the session's previous one);
  // newly published meshes arrive through on_chunks_published.
  pipeline_.set_view(id_, center, r);
  pump();
}

void ClientSession::handle_edit(const wire::Edit& edit) {
  WireEdit converted = edit_from_wire(edit);
  const uint64_t request = edit.request_id();
  if (converted.edit && edits_in_flight_ >= config_.max_edits_in_flight) {
    // A client cannot queue unbounded work in the shared pipeline.
    converted.edit.reset();
    converted.status = wire::EditResult::TOO_MANY_EDITS;
    converted.reason =
        "over " + std::to_string(config_.max_edits_in_flight) + " edits still being applied";
  }
  if (!converted.edit) {
    if (converted.unknown_enum) send_error(wire::Error::UNKNOWN_ENUM, converted.reason, false);
    wire::Envelope result;
    auto* r = result.mutable_edit_result();
    r->set_request_id(request);
    r->set_status(converted.status);
    r->set_reason(converted.reason);
    queue_control(result);
    return;
  }
  counters_.edits.fetch_add(1, std::memory_order_relaxed);
  ++edits_in_flight_;
  pipeline_.submit(std::move(*converted.edit),
                   [self = shared_from_this(), request](const pipeline::EditResult& r) {
                     wire::Envelope result;  // built on the pipeline thread, queued on the strand
                     auto* w = result.mutable_edit_result();
                     w->set_request_id(request);
                     w->set_status(r.accepted ? wire::EditResult::ACCEPTED : status_of(r.reason));
                     w->set_reason(r.message);
                     for (const ChunkCoord& c : r.changed_chunks)
                       *w->add_changed_chunks() = to_wire(c);
                     asio::post(self->strand_, [self, result = std::move(result)] {
                       --self->edits_in_flight_;
                       self->queue_control(result);
                     });
                   });
}

bool ClientSession::may_see(const std::vector<ChunkCoord>& chunks) const {
  ChunkCoord center;
  int64_t r;
  {
    std::lock_guard lock(view_mutex_);
    center = view_center_;
    r = view_radius_;
  }
  if (r < 0) return false;
  for (const ChunkCoord& c : chunks) {
    const int64_t dx = c.x - center.x, dy = c.y - center.y, dz = c.z - center.z;
    if (dx * dx + dy * dy + dz * dz <= r * r) return true;
  }
  return false;
}

void ClientSession::on_chunks_published(std::shared_ptr<const std::vector<ChunkCoord>> chunks) {
  asio::post(strand_, [self = shared_from_this(), chunks = std::move(chunks)] {
    if (self->closing_ || !self->scheduler_.has_view()) return;
    for (const ChunkCoord& c : *chunks) self->scheduler_.mark_stale(c);
    self->pump();
  });
}

void ClientSession::queue_control(const wire::Envelope& message) {
  if (closing_) return;
  control_.push_back(frame_of(message));
  control_bytes_ += control_.back().size();
  if (control_bytes_ > config_.max_control_bytes) {
    spdlog::warn("session {}: '{}' does not read its messages; disconnecting", id_, name_);
    counters_.disconnects.fetch_add(1);
    shutdown();
    return;
  }
  pump();
}

void ClientSession::send_error(wire::Error::Code code, const std::string& message, bool close) {
  if (closing_) return;
  wire::Envelope error;
  error.mutable_error()->set_code(code);
  error.mutable_error()->set_message(message);
  spdlog::info("session {}: {} ({}){}", id_, wire::Error::Code_Name(code), message,
               close ? ", closing" : "");
  queue_control(error);
  if (close) {
    closing_ = true;
    counters_.disconnects.fetch_add(1);
    // Give the Error a moment to leave, then close whatever happens.
    write_timer_.expires_after(std::chrono::seconds(1));
    write_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
      if (!ec) self->shutdown();
    });
    pump();
  }
}

void ClientSession::close_with_error(wire::Error::Code code, std::string message) {
  asio::post(strand_, [self = shared_from_this(), code, message = std::move(message)] {
    self->send_error(code, message, true);
  });
}

// Appends the newest version of the nearest stale chunk the client does not hold yet
// (a delta when it holds an older one); false when nothing is left to send.
bool ClientSession::append_next_mesh(std::vector<uint8_t>& out) {
  const auto send = scheduler_.next([this](ChunkCoord c) { return pipeline_.meshes().get(c); });
  if (!send) return false;
  // One message object reused for every mesh: its payload string keeps its capacity.
  auto* m = mesh_message_.mutable_chunk_mesh();
  *m->mutable_coord() = to_wire(send->coord);
  m->set_version(send->version->version);
  if (send->base) {
    const auto delta = send->version->delta_from(*send->base);
    m->set_base_version(send->base->version);
    m->set_payload(delta->data(), delta->size());
    counters_.deltas_sent.fetch_add(1, std::memory_order_relaxed);
  } else {
    m->set_base_version(0);
    m->set_payload(send->version->full_frame.data(), send->version->full_frame.size());
  }
  append_framed(mesh_message_, out);
  counters_.meshes_sent.fetch_add(1, std::memory_order_relaxed);
  return true;
}

void ClientSession::pump() {
  if (writing_ || !socket_.is_open()) return;
  write_buffer_.clear();
  while (!control_.empty() && write_buffer_.size() < config_.max_bytes_in_flight) {
    write_buffer_.insert(write_buffer_.end(), control_.front().begin(), control_.front().end());
    control_bytes_ -= control_.front().size();
    control_.pop_front();
  }
  if (!closing_) {
    while (write_buffer_.size() < config_.max_bytes_in_flight && append_next_mesh(write_buffer_)) {
    }
  }
  if (write_buffer_.empty()) return;
  writing_ = true;
  if (!closing_) {
    write_timer_.expires_after(config_.write_timeout);
    write_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
      if (ec || !self->writing_) return;
      spdlog::warn("session {}: '{}' stopped reading (a write took over {} ms); disconnecting",
                   self->id_, self->name_, self->config_.write_timeout.count());
      self->counters_.disconnects.fetch_add(1);
      self->shutdown();
    });
  }
  asio::async_write(socket_, asio::buffer(write_buffer_),
                    asio::bind_executor(strand_, [self = shared_from_this()](
                                                     boost::system::error_code ec, size_t n) {
                      self->writing_ = false;
                      self->counters_.bytes_sent.fetch_add(n, std::memory_order_relaxed);
                      if (ec) {
                        self->shutdown();
                        return;
                      }
                      if (self->closing_ && self->control_.empty()) {
                        self->shutdown();
                        return;
                      }
                      if (!self->closing_) self->write_timer_.cancel();
                      self->pump();
                    }));
}

void ClientSession::shutdown() {
  closing_ = true;
  handshake_timer_.cancel();
  idle_timer_.cancel();
  write_timer_.cancel();
  if (socket_.is_open()) {
    boost::system::error_code ignored;
    socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
    if (player_) spdlog::info("session {}: player '{}' left", id_, name_);
  }
  scheduler_.clear();
  control_.clear();
  pipeline_.drop_view(id_);  // its queued loads go with it
}

}  // namespace vox::net
