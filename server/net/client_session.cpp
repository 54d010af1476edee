// The session's lifecycle, what its connection tells it (messages and their rate, writes,
// the end) and what it writes; the message handlers are in session_handlers.cpp.
#include "server/net/client_session.hpp"

#include <spdlog/spdlog.h>

#include "proto/mesh_codec.hpp"
#include "server/net/wire_convert.hpp"

namespace vox::net {

using world::ChunkCoord;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<uint8_t> serialized(const wire::Envelope& message) {
  std::vector<uint8_t> out(message.ByteSizeLong());
  message.SerializeWithCachedSizesToArray(out.data());
  return out;
}

}  // namespace

ClientSession::ClientSession(std::unique_ptr<Connection> connection, std::string address,
                             uint64_t id, pipeline::WorldPipeline& pipeline,
                             SessionServices services)
    : connection_(std::move(connection)),
      strand_(connection_->strand()),
      handshake_timer_(strand_),
      idle_timer_(strand_),
      close_timer_(strand_),
      read_pause_timer_(strand_),
      view_timer_(strand_),
      address_(std::move(address)),
      id_(id),
      services_(std::move(services)),
      config_(*services_.config),
      pipeline_(pipeline),
      counters_(services_.counters),
      edits_(pipeline.config().limits, config_.max_edits_in_flight),
      view_budget_(config_.set_view_rate, config_.set_view_burst),
      message_budget_(config_.message_rate, config_.message_burst),
      error_budget_(config_.protocol_error_rate, config_.protocol_error_burst) {
  counters_.handshaking.fetch_add(1, std::memory_order_relaxed);
}

ClientSession::~ClientSession() {
  (player_ ? counters_.players : counters_.handshaking).fetch_sub(1);
  counters_.session_bytes.fetch_sub(memory_bytes_.load(), std::memory_order_relaxed);
  services_.admission->release(address_, player_);
  if (!player_id_.empty()) services_.players->release(player_id_, this);
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
    self->update_memory();
    self->connection_->read(self->events());
  });
}

// Idle means no complete message: bytes trickled in do not count.
void ClientSession::arm_idle_timer() {
  idle_timer_.expires_after(config_.idle_timeout);
  idle_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (!ec && !self->closing_)
      self->send_error(wire::Error::IDLE_TIMEOUT, "no complete message for too long", true);
  });
}

// A message from the client: handled; then, over its message rate, the connection stops
// reading for a while (TCP pushes back on the client) and reads on.
bool ClientSession::on_message(std::span<const uint8_t> body) {
  if (closing_) return false;  // nothing more is handled once the session closes
  arm_idle_timer();
  on_frame(body);
  if (closing_) return false;
  const auto wait = message_budget_.take(1, Clock::now());
  if (wait.count() <= 0) return true;
  ServerCounters::bump(counters_.reads_paused);
  read_pause_timer_.expires_after(std::min(wait, std::chrono::milliseconds(1000)));
  read_pause_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (ec || self->closing_) return;
    self->connection_->read(self->events());
  });
  return false;
}

void ClientSession::on_stream_error(wire::Error::Code code, const std::string& why) {
  send_error(code, why, true);
}

void ClientSession::on_closed() {
  if (!closing_) spdlog::debug("session {}: connection closed by peer", id_);
  shutdown();
}

void ClientSession::on_write_timeout() {
  drop_slow(DroppedBy::kWriteTimeout, "stopped reading (a write took too long)");
}

void ClientSession::on_written(size_t bytes) {
  counters_.bytes_sent.fetch_add(bytes, std::memory_order_relaxed);
  if (closing_ && control_.empty()) {
    shutdown();
    return;
  }
  observe_written_edits();
  update_memory();
  pump();
}

void ClientSession::on_frame(std::span<const uint8_t> body) {
  wire::Envelope message;
  if (!message.ParseFromArray(body.data(), static_cast<int>(body.size()))) {
    send_error(wire::Error::MALFORMED, "the frame is not a valid Envelope", true);
    return;
  }
  if (!player_ && message.body_case() != wire::Envelope::kHello) {
    send_error(wire::Error::NOT_HELLO, "the first message must be Hello", true);
    return;
  }
  if (has_unknown_fields(message)) {
    // An Edit still gets its one EditResult.
    if (message.body_case() == wire::Envelope::kEdit && player_) {
      queue_result(message.edit().request_id(), wire::EditResult::BAD_VALUE,
                   "the edit has fields this protocol version does not define");
    }
    send_error(wire::Error::UNKNOWN_MESSAGE,
               "the message has fields this protocol version does not define", false);
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
    case wire::Envelope::kResync:
      handle_resync(message.resync());
      break;
    case wire::Envelope::kRegionCommand:
      handle_region_command(message.region_command());
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

void ClientSession::queue_control(const wire::Envelope& message) {
  if (closing_) return;
  control_.push_back(serialized(message));
  control_bytes_ += control_.back().size();
  if (control_bytes_ > config_.max_control_bytes) {
    drop_slow(DroppedBy::kSlowReader, "does not read its messages");
    return;
  }
  pump();
}

// Protocol errors: logged at most once per second per code (with a count of the others),
// counted, sent; a client that keeps making kept-connection errors is closed.
void ClientSession::send_error(wire::Error::Code code, const std::string& message, bool close) {
  if (closing_) return;
  if (!close && error_budget_.take(1, Clock::now()).count() > 0) close = true;
  const auto kind = static_cast<size_t>(code);
  if (kind < counters_.errors_sent.size()) ServerCounters::bump(counters_.errors_sent[kind]);
  const std::string& name = wire::Error::Code_Name(code);
  if (auto suppressed = services_.logs->allow("error:" + name)) {
    spdlog::info("session {}: {} ({}){}{}", id_, name, escape_for_log(message, 200),
                 close ? ", closing" : "",
                 *suppressed
                     ? fmt::format(" [{} more {} since the last such line]", *suppressed, name)
                     : std::string());
  }
  wire::Envelope error;
  error.mutable_error()->set_code(code);
  error.mutable_error()->set_message(message);
  queue_control(error);
  if (close) {
    closing_ = true;
    counters_.disconnects.fetch_add(1);
    // Give the Error a moment to leave, then close whatever happens.
    close_timer_.expires_after(std::chrono::seconds(1));
    close_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
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

void ClientSession::drop_slow(DroppedBy why, const char* what) {
  ServerCounters::bump(counters_.dropped[static_cast<size_t>(why)]);
  counters_.disconnects.fetch_add(1);
  if (auto suppressed = services_.logs->allow(std::string("dropped:") + what)) {
    spdlog::warn("session {}: '{}' {}; disconnecting{}", id_, log_name_, what,
                 *suppressed ? fmt::format(" [{} more since the last such line]", *suppressed)
                             : std::string());
  }
  shutdown();
}

// Appends the newest version of the nearest stale chunk the client does not hold yet
// (a delta when it holds an older one); false when nothing is left to send.
bool ClientSession::append_next_mesh() {
  // No version that may show an edit of this client goes out before the edit's result.
  const auto send = scheduler_.next([this](ChunkCoord c) { return pipeline_.meshes().get(c); },
                                    results_.first_unsendable_version());
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
    if (send->version->edited_at != Clock::time_point{})
      write_edits_.push_back(send->version->edited_at);
  } else {
    m->set_base_version(0);
    const std::span<const uint8_t> full = send->version->full();
    m->set_payload(full.data(), full.size());
  }
  connection_->append(mesh_message_);
  counters_.meshes_sent.fetch_add(1, std::memory_order_relaxed);
  return true;
}

// Once per applied view, when its every chunk (of every level) has been sent or found
// empty; true when it was appended.
bool ClientSession::append_view_ready() {
  if (!level0_done_) level0_done_ = scheduler_.take_view_complete();
  if (!level0_done_) return false;
  if (lod_view_ && !lod_done_) lod_done_ = lod_queue_.take_complete();
  if (lod_view_ && !lod_done_) return false;
  wire::Envelope ready;
  auto* r = ready.mutable_view_ready();
  r->set_view_id(view_id_);
  *r->mutable_center() = to_wire(view_center_);  // strand: its only writer
  r->set_radius(static_cast<uint32_t>(view_radius_));
  r->set_chunks_sent(level0_done_->sent);
  r->set_chunks_empty(level0_done_->empty);
  if (lod_done_) {
    r->set_lod_chunks_sent(lod_done_->sent);
    r->set_lod_chunks_empty(lod_done_->empty);
  }
  connection_->append(ready);
  level0_done_.reset();
  lod_done_.reset();
  return true;
}

void ClientSession::pump() {
  if (connection_->writing() || applying_view_ || !connection_->open()) return;
  write_edits_.clear();
  const size_t limit = config_.max_bytes_in_flight;
  size_t messages = 0;
  while (!control_.empty() && connection_->pending_bytes() < limit) {
    connection_->append_serialized(control_.front());
    control_bytes_ -= control_.front().size();
    control_.pop_front();
    ++messages;
  }
  if (!closing_) {
    while (connection_->pending_bytes() < limit && append_next_mesh()) ++messages;
    // Coarser levels after every level-0 mesh due (PROTOCOL 4.10), nearest first.
    while (connection_->pending_bytes() < limit && append_next_lod_mesh()) ++messages;
    if (append_view_ready()) ++messages;  // after the view's last first mesh
  }
  if (connection_->pending_bytes() == 0) return;
  counters_.messages_sent.fetch_add(messages, std::memory_order_relaxed);
  // Closing: no deadline of its own (the close timer ends it).
  connection_->write(events(), closing_ ? std::chrono::milliseconds(0) : config_.write_timeout);
}

// Strand, after a write completed: the kernel has every delta it carried.
void ClientSession::observe_written_edits() {
  if (write_edits_.empty()) return;
  const auto now = Clock::now();
  for (const auto submitted : write_edits_) {
    counters_.edit_to_delta_written.observe(std::chrono::duration<double>(now - submitted).count());
  }
  write_edits_.clear();
}

// The session's accounted memory: its view map and send queues, queued control frames,
// the write and read buffers and a partial frame.
void ClientSession::update_memory() {
  // Map node (~64) + an entry in the updates or new-chunk heap (24), in the waiting heap
  // (24) and in the deferred list (12), at most.
  constexpr size_t kPerVisibleChunk = 128;
  // A layout chunk: in the LodView's leaves and held map, the LodSendQueue and the
  // level-0 set.
  constexpr size_t kPerLodChunk = 384;
  const size_t lod_chunks = lod_view_ ? lod_view_->held().size() : 0;
  const size_t bytes = sizeof(ClientSession) + scheduler_.visible_count() * kPerVisibleChunk +
                       lod_chunks * kPerLodChunk + control_bytes_ + connection_->memory_bytes() +
                       results_.size() * 64;
  const size_t old = memory_bytes_.exchange(bytes, std::memory_order_relaxed);
  counters_.session_bytes.fetch_add(bytes - old, std::memory_order_relaxed);  // wraps: exact
}

void ClientSession::shutdown() {
  closing_ = true;
  handshake_timer_.cancel();
  idle_timer_.cancel();
  close_timer_.cancel();
  read_pause_timer_.cancel();
  view_timer_.cancel();
  if (connection_->open()) {
    connection_->close();
    if (player_) {
      if (auto suppressed = services_.logs->allow("left", 20)) {
        spdlog::info("session {}: player '{}' left{}", id_, log_name_,
                     *suppressed ? fmt::format(" [{} more left]", *suppressed) : std::string());
      }
    }
  }
  if (!player_id_.empty()) services_.players->release(player_id_, this);
  scheduler_.clear();
  lod_queue_.clear();
  lod_view_.reset();
  lod_active_.store(false, std::memory_order_relaxed);
  control_.clear();
  control_bytes_ = 0;
  pending_view_.reset();
  pipeline_.drop_view(id_);  // its queued loads go with it
  update_memory();
}

}  // namespace vox::net
