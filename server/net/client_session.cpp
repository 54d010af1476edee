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

// The feed's wants, as the pipeline's wants of this session; `budget_group`: its address.
ViewFeed::Wants pipeline_wants(pipeline::WorldPipeline& pipeline, uint64_t owner,
                               uint64_t budget_group) {
  return {.set_view =
              [&pipeline, owner, budget_group](ChunkCoord center, int radius,
                                               const SendScheduler::Keep& keep) {
                pipeline.set_view(owner, center, radius, budget_group, keep);
              },
          .set_lod_view =
              [&pipeline, owner](std::vector<pipeline::LodKey> keys) {
                pipeline.set_lod_view(owner, std::move(keys));
              }};
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
      error_budget_(config_.protocol_error_rate, config_.protocol_error_burst),
      queries_(pipeline.config().limits,
               QueryLimits{.max_distance = config_.max_query_distance,
                           .max_samples = config_.max_query_samples,
                           .max_in_flight = config_.max_queries_in_flight,
                           .rate = config_.query_rate,
                           .cluster = pipeline.config().zones != nullptr}),
      feed_(pipeline.meshes(), pipeline.lod_meshes(),
            pipeline_wants(pipeline, id_, std::hash<std::string>{}(address_) | 1),  // never 0
            counters_) {
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

std::optional<PlayerCard> ClientSession::card() const {  // any thread
  // The fields below are written once, on the strand, before player_ is set.
  if (!player_.load(std::memory_order_acquire) || leaving_.load(std::memory_order_relaxed))
    return std::nullopt;
  return PlayerCard{id_,
                    player_id_,
                    name_,
                    address_,
                    role_,
                    connected_unix_ms_,
                    edits_accepted_.load(std::memory_order_relaxed),
                    bytes_sent_.load(std::memory_order_relaxed)};
}

void ClientSession::on_written(size_t bytes) {
  counters_.bytes_sent.fetch_add(bytes, std::memory_order_relaxed);
  bytes_sent_.fetch_add(bytes, std::memory_order_relaxed);
  if (closing_ && control_.empty()) {
    shutdown();
    return;
  }
  feed_.written();
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
    if (message.body_case() == wire::Envelope::kQuery && player_) {  // and a Query its answer
      wire::Envelope reply;
      auto* r = reply.mutable_query_result();
      r->set_request_id(message.query().request_id());
      r->set_status(wire::QueryResult::BAD_VALUE);
      r->set_reason("the query has fields this protocol version does not define");
      queue_control(reply);
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
    case wire::Envelope::kAdminCommand:
      handle_admin_command(message.admin_command());
      break;
    case wire::Envelope::kQuery:
      handle_query(message.query());
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
void ClientSession::send_error(wire::Error::Code code, const std::string& message, bool close,
                               int64_t banned_until_unix_ms) {
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
  error.mutable_error()->set_banned_until_unix_ms(banned_until_unix_ms);
  queue_control(error);
  if (close) {
    closing_ = true;
    leaving_.store(true, std::memory_order_relaxed);
    counters_.disconnects.fetch_add(1);
    // Give the Error a moment to leave, then close whatever happens.
    close_timer_.expires_after(std::chrono::seconds(1));
    close_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
      if (!ec) self->shutdown();
    });
    pump();
  }
}

void ClientSession::close_with_error(wire::Error::Code code, std::string message,
                                     int64_t banned_until_unix_ms) {
  leaving_.store(true, std::memory_order_relaxed);
  asio::post(strand_,
             [self = shared_from_this(), code, message = std::move(message), banned_until_unix_ms] {
               self->send_error(code, message, true, banned_until_unix_ms);
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

void ClientSession::pump() {
  if (connection_->writing() || applying_view_ || !connection_->open()) return;
  feed_.begin_write();
  const size_t limit = config_.max_bytes_in_flight;
  size_t messages = 0;
  while (!control_.empty() && connection_->pending_bytes() < limit) {
    connection_->append_serialized(control_.front());
    control_bytes_ -= control_.front().size();
    control_.pop_front();
    ++messages;
  }
  if (!closing_) {
    // No version that may show an edit of this client goes out before the edit's result.
    const uint64_t first_unsendable = results_.first_unsendable_version();
    while (connection_->pending_bytes() < limit) {
      const wire::Envelope* mesh = feed_.next_mesh(first_unsendable);
      if (!mesh) break;
      connection_->append(*mesh);
      ++messages;
    }
    wire::Envelope ready;
    if (feed_.take_view_ready(ready)) {  // after the view's last first mesh
      connection_->append(ready);
      ++messages;
    }
  }
  if (connection_->pending_bytes() == 0) return;
  counters_.messages_sent.fetch_add(messages, std::memory_order_relaxed);
  // Closing: no deadline of its own (the close timer ends it).
  connection_->write(events(), closing_ ? std::chrono::milliseconds(0) : config_.write_timeout);
}

// The session's accounted memory: its view map and send queues, queued control frames,
// the write and read buffers and a partial frame.
void ClientSession::update_memory() {
  const size_t bytes = sizeof(ClientSession) + feed_.memory_bytes() + control_bytes_ +
                       connection_->memory_bytes() + results_.size() * 64;
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
  feed_.clear();
  control_.clear();
  control_bytes_ = 0;
  pending_view_.reset();
  pipeline_.drop_view(id_);  // its queued loads go with it
  update_memory();
}

void ClientSession::on_lod_published(  // any thread
    std::shared_ptr<const std::vector<pipeline::LodKey>> keys) {
  asio::post(strand_, [self = shared_from_this(), keys = std::move(keys)] {
    if (self->closing_) return;
    if (self->feed_.lod_published(*keys)) self->pump();
  });
}

}  // namespace vox::net
