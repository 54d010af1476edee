// The session's lifecycle, read chain (frames, rate, timeouts) and write chain; the
// message handlers are in session_handlers.cpp.
#include "server/net/client_session.hpp"

#include <spdlog/spdlog.h>

#include "proto/mesh_codec.hpp"
#include "server/net/wire_convert.hpp"

namespace vox::net {

using world::ChunkCoord;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<uint8_t> frame_of(const wire::Envelope& message) {
  std::vector<uint8_t> out;
  proto::append_framed(message, out);
  return out;
}

}  // namespace

ClientSession::ClientSession(asio::ip::tcp::socket socket, std::string address, uint64_t id,
                             pipeline::WorldPipeline& pipeline, SessionServices services)
    : socket_(std::move(socket)),
      strand_(asio::make_strand(socket_.get_executor())),
      handshake_timer_(strand_),
      idle_timer_(strand_),
      write_timer_(strand_),
      frame_timer_(strand_),
      read_pause_timer_(strand_),
      view_timer_(strand_),
      address_(std::move(address)),
      id_(id),
      services_(std::move(services)),
      config_(*services_.config),
      pipeline_(pipeline),
      counters_(services_.counters),
      decoder_(config_.max_frame_bytes),
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
    self->read_more();
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

void ClientSession::read_more() {
  if (closing_ || reading_paused_) return;
  socket_.async_read_some(asio::buffer(read_buffer_),
                          asio::bind_executor(strand_, [self = shared_from_this()](
                                                           boost::system::error_code ec, size_t n) {
                            if (ec) {
                              if (!self->closing_)
                                spdlog::debug("session {}: connection closed by peer ({})",
                                              self->id_, ec.message());
                              self->shutdown();
                              return;
                            }
                            self->decoder_.feed({self->read_buffer_.data(), n});
                            self->process_frames();
                          }));
}

// Handles the complete frames buffered; stops reading for a while when the client sends
// faster than its message rate (TCP pushes back on it), then reads on.
void ClientSession::process_frames() {
  bool completed = false;
  while (auto frame = decoder_.next()) {
    completed = true;
    arm_idle_timer();
    on_frame(*frame);
    if (closing_) return;
    const auto wait = message_budget_.take(1, Clock::now());
    if (wait.count() > 0) {
      reading_paused_ = true;
      ServerCounters::bump(counters_.reads_paused);
      read_pause_timer_.expires_after(std::min(wait, std::chrono::milliseconds(1000)));
      read_pause_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
        if (ec || self->closing_) return;
        self->reading_paused_ = false;
        self->process_frames();
      });
      return;
    }
  }
  if (!decoder_.error().empty()) {
    send_error(wire::Error::FRAME_TOO_LARGE, decoder_.error(), true);
    return;
  }
  // A partial frame left after complete ones started in this read.
  if (decoder_.buffered() == 0) {
    partial_since_.reset();
  } else if (completed || !partial_since_) {
    partial_since_ = Clock::now();
  }
  watch_partial_frame();
  read_more();
}

// A frame that has started must finish within the frame timeout, so a client cannot hold
// a connection by trickling bytes.
void ClientSession::watch_partial_frame() {
  if (!partial_since_ || frame_watch_) return;
  frame_watch_ = true;
  frame_timer_.expires_at(*partial_since_ + config_.frame_timeout);
  frame_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    self->frame_watch_ = false;
    if (ec || self->closing_ || !self->partial_since_) return;
    if (Clock::now() >= *self->partial_since_ + self->config_.frame_timeout) {
      self->send_error(wire::Error::FRAME_TIMEOUT,
                       "a frame was not completed within the frame timeout", true);
      return;
    }
    self->watch_partial_frame();  // a later frame is partial now: watch it
  });
}

void ClientSession::on_frame(const std::vector<uint8_t>& body) {
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
  control_.push_back(frame_of(message));
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
bool ClientSession::append_next_mesh(std::vector<uint8_t>& out) {
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
  proto::append_framed(mesh_message_, out);
  counters_.meshes_sent.fetch_add(1, std::memory_order_relaxed);
  return true;
}

// Once per applied view, when its every chunk (of every level) has been sent or found
// empty.
void ClientSession::append_view_ready(std::vector<uint8_t>& out) {
  if (!level0_done_) level0_done_ = scheduler_.take_view_complete();
  if (!level0_done_) return;
  if (lod_view_ && !lod_done_) lod_done_ = lod_queue_.take_complete();
  if (lod_view_ && !lod_done_) return;
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
  proto::append_framed(ready, out);
  level0_done_.reset();
  lod_done_.reset();
}

void ClientSession::pump() {
  if (writing_ || applying_view_ || !socket_.is_open()) return;
  write_buffer_.clear();
  write_edits_.clear();
  size_t messages = 0;
  while (!control_.empty() && write_buffer_.size() < config_.max_bytes_in_flight) {
    write_buffer_.insert(write_buffer_.end(), control_.front().begin(), control_.front().end());
    control_bytes_ -= control_.front().size();
    control_.pop_front();
    ++messages;
  }
  if (!closing_) {
    while (write_buffer_.size() < config_.max_bytes_in_flight && append_next_mesh(write_buffer_)) {
      ++messages;
    }
    // Coarser levels after every level-0 mesh due (PROTOCOL 4.10), nearest first.
    while (write_buffer_.size() < config_.max_bytes_in_flight &&
           append_next_lod_mesh(write_buffer_)) {
      ++messages;
    }
    const size_t before = write_buffer_.size();
    append_view_ready(write_buffer_);  // after the view's last first mesh
    if (write_buffer_.size() > before) ++messages;
  }
  if (write_buffer_.empty()) return;
  counters_.messages_sent.fetch_add(messages, std::memory_order_relaxed);
  writing_ = true;
  if (!closing_) {
    write_timer_.expires_after(config_.write_timeout);
    write_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
      if (ec || !self->writing_) return;
      self->drop_slow(DroppedBy::kWriteTimeout, "stopped reading (a write took too long)");
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
                      self->observe_written_edits();
                      self->update_memory();
                      self->pump();
                    }));
}

// Strand, after a write completed: the kernel has every delta of write_buffer_.
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
                       lod_chunks * kPerLodChunk + control_bytes_ + write_buffer_.capacity() +
                       decoder_.buffered() + results_.size() * 64;
  const size_t old = memory_bytes_.exchange(bytes, std::memory_order_relaxed);
  counters_.session_bytes.fetch_add(bytes - old, std::memory_order_relaxed);  // wraps: exact
}

void ClientSession::shutdown() {
  closing_ = true;
  handshake_timer_.cancel();
  idle_timer_.cancel();
  write_timer_.cancel();
  frame_timer_.cancel();
  read_pause_timer_.cancel();
  view_timer_.cancel();
  if (socket_.is_open()) {
    boost::system::error_code ignored;
    socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
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
