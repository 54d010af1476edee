// The session's message handlers: Hello (admission), SetView (checks, rate, coalescing;
// then the feed), Edit (budget, ordered results), and the publish fan-out's entry points.
// Strand only, but where a comment says otherwise.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "proto/mesh_codec.hpp"
#include "server/net/client_session.hpp"
#include "server/net/wire_convert.hpp"
#include "server/pipeline/edit_ids.hpp"

namespace vox::net {

using world::ChunkCoord;
using Clock = std::chrono::steady_clock;

namespace {

bool finite(const wire::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

}  // namespace

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
  std::optional<auth::PlayerClaims> claims;
  const LiveValues live = services_.live->get();
  if (live.auth_key) {
    claims = verify_hello_token(hello, *live.auth_key);
    if (!claims) return;
  } else if (hello.player_name().empty() || hello.player_name().size() > 32) {
    send_error(wire::Error::BAD_VALUE, "player_name must be 1..32 bytes", true);
    return;
  }
  if (refuse_if_banned(claims ? claims->player_id : "", claims ? claims->role : config_.open_role))
    return;
  if (services_.admission->promote(address_) != AdmissionControl::Verdict::kAdmit) {
    ServerCounters::bump(counters_.refused[static_cast<size_t>(RefusedBy::kServerFull)]);
    send_error(wire::Error::SERVER_FULL,
               "the server is full (" + std::to_string(services_.admission->limits().max_players) +
                   " players)",
               true);
    return;
  }
  name_ = claims ? claims->display_name : hello.player_name();
  log_name_ = escape_for_log(name_);
  role_ = claims ? claims->role : config_.open_role;
  claims_ = claims;
  if (claims)
    join_as(*claims, live);
  else
    edits_.join(role_, std::make_shared<SharedEditBudget>(edit_limits(nullptr, live)));
  connected_unix_ms_ = BanKeeper::now_ms();
  player_.store(true, std::memory_order_release);
  counters_.handshaking.fetch_sub(1);
  const uint64_t players = counters_.players.fetch_add(1) + 1;
  handshake_timer_.cancel();
  send_welcome(players);
  if (auto suppressed = services_.logs->allow("joined", 20)) {
    spdlog::info("session {}: player '{}' ({}{}) joined from {}{}", id_, log_name_,
                 player_id_.empty() ? "" : "id " + escape_for_log(player_id_) + ", ",
                 auth::to_string(role_), address_,
                 *suppressed ? fmt::format(" [{} more joined]", *suppressed) : std::string());
  }
  // A ban made while this Hello was being checked: the admin's sweep of the players may
  // have run before this session was one, so it looks again now that it is.
  refuse_if_banned(player_id_, role_);
}

// A ban in force for `player_id` or this connection's address: counted, logged, told
// (BANNED with the reason and the end) and closed. Admins are never held by an address
// ban (one could lock every admin behind a shared address out). Returns whether banned.
bool ClientSession::refuse_if_banned(const std::string& player_id, auth::Role role) {
  std::optional<store::Ban> ban = services_.bans->match(player_id, address_);
  if (ban && ban->kind == store::Ban::Kind::kAddress && role == auth::Role::kAdmin)
    ban = services_.bans->match(player_id, "");
  if (!ban) return false;
  ServerCounters::bump(counters_.refused[static_cast<size_t>(RefusedBy::kBanned)]);
  if (auto suppressed = services_.logs->allow("banned", 10)) {
    spdlog::info("session {}: {} {} is banned: refused{}", id_, store::to_string(ban->kind),
                 escape_for_log(ban->target),
                 *suppressed ? fmt::format(" [{} more refused]", *suppressed) : std::string());
  }
  send_error(wire::Error::BANNED, describe_ban(*ban), true, ban->until_ms);
  return true;
}

std::optional<auth::PlayerClaims> ClientSession::verify_hello_token(const wire::Hello& hello,
                                                                    const auth::PublicKey& key) {
  const int64_t now = std::chrono::duration_cast<std::chrono::seconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  auth::VerifiedToken v = auth::verify_token(hello.token(), key, now);
  if (v.claims) return std::move(v.claims);
  ServerCounters::bump(counters_.refused[static_cast<size_t>(RefusedBy::kToken)]);
  send_error(v.error == auth::TokenError::kMissing   ? wire::Error::AUTH_REQUIRED
             : v.error == auth::TokenError::kExpired ? wire::Error::TOKEN_EXPIRED
                                                     : wire::Error::BAD_TOKEN,
             v.message, true);
  return std::nullopt;
}

void ClientSession::join_as(const auth::PlayerClaims& claims, const LiveValues& live) {
  player_id_ = claims.player_id;
  auto [previous, budget] =
      services_.players->claim(player_id_, shared_from_this(), edit_limits(&claims, live));
  edits_.join(role_, std::move(budget));
  if (!previous) return;
  previous->close_with_error(wire::Error::REPLACED, "another connection joined as this player");
  if (auto suppressed = services_.logs->allow("replaced", 20)) {
    spdlog::info("session {}: player '{}' ({}) replaces session {}{}", id_, log_name_,
                 escape_for_log(player_id_), previous->id(),
                 *suppressed ? fmt::format(" [{} more replaced]", *suppressed) : std::string());
  }
}

void ClientSession::reload_budget(const LiveValues& live) {
  asio::post(strand_, [self = shared_from_this(), live] {
    if (!self->player_.load(std::memory_order_acquire)) return;  // its Hello reads them
    self->edits_.set_budget_limits(
        self->edit_limits(self->claims_ ? &*self->claims_ : nullptr, live), Clock::now());
  });
}

BudgetLimits ClientSession::edit_limits(const auth::PlayerClaims* claims,
                                        const LiveValues& live) const {
  const EditBudgetPolicy policy({live.edit_budget_rate, live.edit_budget_burst},
                                {live.admin_edit_budget_rate, live.admin_edit_budget_burst});
  // Without a token (an open server) every client has the player's budget, whatever
  // --open-role says: anyone may connect.
  return policy.limits_for(claims ? role_ : auth::Role::kPlayer, claims ? claims->edit_rate : 0,
                           claims ? claims->edit_burst : 0,
                           world::max_touched_samples(pipeline_.config().limits));
}

void ClientSession::send_welcome(uint64_t players) {
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
  const BudgetLimits budget = edits_.budget()->limits();
  w->set_edit_budget_per_second(std::max(0.0, budget.rate));
  w->set_edit_budget_burst(budget.rate > 0 ? budget.burst : 0);
  w->set_max_set_views_per_second(std::max(0.0, config_.set_view_rate));
  w->set_max_connections_per_address(
      static_cast<uint32_t>(services_.admission->limits().max_per_address));
  w->set_max_resync_chunks(static_cast<uint32_t>(config_.max_resync_chunks));
  w->set_mesh_table_revision(proto::kMeshTableRevision);
  w->set_max_lod_level(
      std::min<uint32_t>(config_.max_lod_level,
                         static_cast<uint32_t>(std::max(0, pipeline_.config().lod.levels - 1))));
  w->set_max_lod_distance(config_.max_lod_distance);
  w->set_max_query_distance(config_.max_query_distance);
  w->set_max_query_samples(config_.max_query_samples);
  w->set_max_queries_in_flight(static_cast<uint32_t>(config_.max_queries_in_flight));
  w->set_queries_per_second(std::max(0.0, config_.query_rate));
  queue_control(welcome);
}

void ClientSession::handle_set_view(const wire::SetView& view) {
  const auto& limits = pipeline_.config().limits;
  if (!finite(view.position())) {
    send_error(wire::Error::BAD_VALUE, "SetView position must be finite", false);
    return;
  }
  const float p[3] = {view.position().x(), view.position().y(), view.position().z()};
  if (!world::inside_world(limits, p[0], p[1], p[2])) {
    send_error(wire::Error::BAD_VALUE, "SetView position is outside the world", false);
    return;
  }
  if (view.radius() > config_.max_view_radius) {
    send_error(wire::Error::BAD_VALUE,
               "view radius " + std::to_string(view.radius()) + " is over the limit of " +
                   std::to_string(config_.max_view_radius),
               false);
    return;
  }
  PendingView v;
  if (!check_lod(view, v)) return;
  v.radius = static_cast<int>(view.radius());
  v.center = world::chunk_of_voxel(static_cast<int32_t>(std::floor(p[0])),
                                   static_cast<int32_t>(std::floor(p[1])),
                                   static_cast<int32_t>(std::floor(p[2])));
  v.eye = {p[0], p[1], p[2]};
  v.view_id = view.view_id();
  // Over the SetView rate, the newest view waits for the next token; older ones are
  // coalesced into it.
  if (pending_view_) {
    pending_view_ = v;
    ServerCounters::bump(counters_.set_views_coalesced);
    return;
  }
  const auto wait = view_budget_.take(1, Clock::now());
  if (wait.count() == 0) {
    apply_view(v);
    return;
  }
  pending_view_ = v;
  ServerCounters::bump(counters_.set_views_coalesced);
  view_timer_.expires_after(wait);
  view_timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (ec || self->closing_ || !self->pending_view_) return;
    const PendingView pending = *self->pending_view_;
    self->pending_view_.reset();
    (void)self->view_budget_.take(1, Clock::now());
    self->apply_view(pending);
  });
}

void ClientSession::apply_view(const PendingView& v) {
  // The unloads go in one write, before anything of the new view: no pump on the way.
  applying_view_ = true;
  for (const wire::Envelope& unload : feed_.apply_view(v)) queue_control(unload);
  applying_view_ = false;
  update_memory();
  pump();
}

// Full copies of chunks the client dropped; coordinates outside the view are ignored (the
// client cannot hold them).
void ClientSession::handle_resync(const wire::Resync& resync) {
  if (static_cast<size_t>(resync.coords_size()) > config_.max_resync_chunks) {
    send_error(wire::Error::BAD_VALUE,
               "Resync carries " + std::to_string(resync.coords_size()) +
                   " chunks, over the limit of " + std::to_string(config_.max_resync_chunks),
               false);
    return;
  }
  // Each chunk costs a message of the client's message rate (the frame itself paid one):
  // a Resync of 64 full copies must not cost what one Ping does.
  if (resync.coords_size() > 1) message_budget_.charge(resync.coords_size() - 1, Clock::now());
  if (!feed_.has_view()) return;
  size_t queued = 0;
  const int level = static_cast<int>(std::min<uint32_t>(resync.level(), config_.max_lod_level + 1));
  for (const auto& c : resync.coords()) queued += feed_.resync(level, from_wire(c));
  counters_.chunks_resynced.fetch_add(queued, std::memory_order_relaxed);
  pump();
}

void ClientSession::queue_result(uint64_t request, wire::EditResult::Status status,
                                 const std::string& reason, uint32_t retry_after_ms) {
  wire::Envelope result;
  auto* r = result.mutable_edit_result();
  r->set_request_id(request);
  r->set_status(status);
  r->set_reason(reason);
  r->set_retry_after_ms(retry_after_ms);
  ServerCounters::bump(
      counters_.edit_results[static_cast<size_t>(status) % ServerCounters::kStatuses]);
  log_refusal(status, reason);
  results_.push_ready(std::move(result));
  results_.drain([this](const wire::Envelope& e) { queue_control(e); });
}

void ClientSession::handle_edit(const wire::Edit& edit) {
  WireEdit converted = edit_from_wire(edit);
  const uint64_t request = edit.request_id();
  if (!converted.edit) {
    if (converted.unknown_enum) send_error(wire::Error::UNKNOWN_ENUM, converted.reason, false);
    queue_result(request, converted.status, converted.reason);
    return;
  }
  if (auto refused = edits_.admit(*converted.edit, Clock::now())) {
    queue_result(request, refused->status, refused->reason, refused->retry_after_ms);
    return;
  }
  counters_.edits.fetch_add(1, std::memory_order_relaxed);
  // Read before submitting: every version this edit makes is above it.
  const uint64_t ticket = results_.reserve(pipeline_.meshes().newest_version() + 1);
  const auto submitted = Clock::now();
  pipeline::EditTask task;
  task.edit = std::move(*converted.edit);
  task.done = [self = shared_from_this(), request, ticket,
               submitted](const pipeline::EditResult& r) {
    // Pipeline thread: build the result here, queue it on the strand.
    self->counters_.edit_to_publish.observe(
        std::chrono::duration<double>(Clock::now() - submitted).count());
    asio::post(self->strand_, [self, ticket, result = edit_result_message(request, r),
                               work = r.chunks_generated + r.chunks_expanded]() mutable {
      self->on_edit_result(ticket, std::move(result), work);
    });
  };
  task.owner = id_;
  task.author = player_id_;
  task.bypass_regions = role_ == auth::Role::kAdmin;
  // A resend (the same edit_id) after a lost answer is answered, not applied twice. Without
  // tokens, the name a player gave stands for it.
  task.edit_id =
      pipeline_.edit_id_of(player_id_.empty() ? "name:" + name_ : player_id_, edit.edit_id());
  pipeline_.submit(std::move(task));
}

// Strand: the pipeline's answer, queued in the order of the client's edits.
void ClientSession::on_edit_result(uint64_t ticket, wire::Envelope result, size_t work_chunks) {
  const auto now = Clock::now();
  edits_.answered(work_chunks, now);
  auto* r = result.mutable_edit_result();
  if (r->status() == wire::EditResult::ACCEPTED && !r->already_applied())
    edits_accepted_.fetch_add(1, std::memory_order_relaxed);
  if (r->status() == wire::EditResult::RATE_LIMITED)
    r->set_retry_after_ms(edits_.rate_limited_retry_ms(now));
  ServerCounters::bump(
      counters_.edit_results[static_cast<size_t>(r->status()) % ServerCounters::kStatuses]);
  log_refusal(r->status(), r->reason());
  results_.fill(ticket, std::move(result));
  results_.drain([this](const wire::Envelope& e) { queue_control(e); });
  // The result is queued ahead of any mesh: versions held back for it may go now.
  if (feed_.release_deferred()) pump();
}

// A refused edit, naming its player: a few lines per second per status, with a count of
// the others.
void ClientSession::log_refusal(wire::EditResult::Status status, const std::string& reason) {
  if (status == wire::EditResult::ACCEPTED) return;
  const std::string& name = wire::EditResult::Status_Name(status);
  if (auto suppressed = services_.logs->allow("refused:" + name, 5)) {
    spdlog::info(
        "session {}: player '{}' ({}): edit refused {}: {}{}", id_, log_name_,
        player_id_.empty() ? "no id" : escape_for_log(player_id_), name,
        escape_for_log(reason, 160),
        *suppressed ? fmt::format(" [{} more refused {}]", *suppressed, name) : std::string());
  }
}

void ClientSession::on_chunks_published(  // any thread
    std::shared_ptr<const std::vector<ChunkCoord>> chunks) {
  asio::post(strand_, [self = shared_from_this(), chunks = std::move(chunks)] {
    if (self->closing_) return;
    if (self->feed_.chunks_published(*chunks)) self->pump();
  });
}

// A SetView's level of detail (docs/PROTOCOL.md 4.10): its level and distance checked
// against the limits.
bool ClientSession::check_lod(const wire::SetView& view, PendingView& v) {
  const uint32_t max_level = std::min<uint32_t>(
      config_.max_lod_level, static_cast<uint32_t>(std::max(0, pipeline_.config().lod.levels - 1)));
  if (view.lod_level() > max_level) {
    send_error(wire::Error::BAD_VALUE,
               "lod_level " + std::to_string(view.lod_level()) + " is over the limit of " +
                   std::to_string(max_level),
               false);
    return false;
  }
  const float d = view.lod_distance() == 0.0f ? 1.0f : view.lod_distance();
  if (!std::isfinite(d) || d < 1.0f || d > config_.max_lod_distance) {
    send_error(wire::Error::BAD_VALUE,
               "lod_distance must be 0 or within 1 .. " + std::to_string(config_.max_lod_distance),
               false);
    return false;
  }
  v.lod_level = static_cast<int>(view.lod_level());
  v.lod_distance = d;
  return true;
}

}  // namespace vox::net
