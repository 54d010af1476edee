#include "server/net/server.hpp"

#include <spdlog/spdlog.h>

#include <map>

#include "proto/framing.hpp"
#include "server/net/address_key.hpp"
#include "server/net/proxy_header.hpp"
#include "server/net/tcp_connection.hpp"
#include "server/net/ws_connection.hpp"

namespace vox::net {

namespace {
// After a failed accept (out of descriptors): the wait before the next one.
constexpr auto kAcceptRetry = std::chrono::milliseconds(100);
}  // namespace

Server::Server(asio::io_context& io, ServerConfig config, pipeline::WorldPipeline& pipeline,
               ServerCounters& counters)
    : io_(io),
      strand_(asio::make_strand(io)),
      shared_config_(std::make_shared<const ServerConfig>(std::move(config))),
      config_(*shared_config_),
      pipeline_(pipeline),
      acceptor_(strand_),
      stats_timer_(strand_),
      housekeeping_timer_(strand_),
      accept_retry_timer_(strand_),
      counters_(counters),
      admission_(std::make_shared<AdmissionGate>(
          AdmissionLimits{config_.max_clients, config_.max_handshaking, config_.max_per_address,
                          config_.max_handshaking_per_address})),
      logs_(std::make_shared<SharedLogRateLimit>()),
      players_(std::make_shared<PlayerRegistry<ClientSession>>()),
      publish_(std::make_shared<PublishGate>()),
      sessions_(std::make_shared<SessionDirectory<ClientSession>>()),
      bans_(std::make_shared<BanKeeper>()),
      live_(std::make_shared<LiveSettings>(
          LiveValues{config_.auth_key, config_.edit_budget_rate, config_.edit_budget_burst,
                     config_.admin_edit_budget_rate, config_.admin_edit_budget_burst})) {}

void Server::reload(const LiveValues& live, const AdmissionLimits& caps) {
  live_->set(live);
  for (const auto& s : sessions_->live()) s->reload_budget(live);  // players already in too
  admission_->set_limits(caps);
  if (http_) http_->set_max_per_address(http_per_address_cap(caps.max_per_address));
}

Server::~Server() {
  {
    std::lock_guard lock(publish_->mutex);
    publish_->stopped = true;
  }
  bans_->stop();
  if (subscription_ != 0) pipeline_.unsubscribe(subscription_);
  if (lod_subscription_ != 0) pipeline_.unsubscribe(lod_subscription_);
}

void Server::start() {
  const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(config_.bind), config_.port);
  acceptor_.open(endpoint.protocol());
  acceptor_.set_option(asio::ip::tcp::acceptor::reuse_address(true));
  acceptor_.bind(endpoint);
  acceptor_.listen();
  port_ = acceptor_.local_endpoint().port();
  // Bans found on a reload (another node's, or the table edited): their players go.
  bans_->start([sessions = sessions_](const std::vector<store::Ban>& added) {
    // One pass over the players, however many bans came (an import of thousands).
    std::map<std::pair<store::Ban::Kind, std::string>, const store::Ban*> by_target;
    for (const store::Ban& b : added) by_target.emplace(std::make_pair(b.kind, b.target), &b);
    size_t closed = 0;
    for (const auto& s : sessions->live()) {
      const std::optional<PlayerCard> card = s->card();
      if (!card) continue;
      auto it = card->player_id.empty()
                    ? by_target.end()
                    : by_target.find({store::Ban::Kind::kPlayer, card->player_id});
      if (it == by_target.end() && card->role != auth::Role::kAdmin)
        it = by_target.find({store::Ban::Kind::kAddress, card->address});
      if (it == by_target.end()) continue;
      s->close_with_error(wire::Error::BANNED, describe_ban(*it->second), it->second->until_ms);
      ++closed;
    }
    if (closed)
      spdlog::info("bans: {} new bans from the store closed {} connections", added.size(), closed);
  });
  subscription_ = pipeline_.subscribe([this](const std::vector<world::ChunkCoord>& changed) {
    // Pipeline thread: at once, or gathered while the last fan-out is unhandled.
    std::vector<world::ChunkCoord> now;
    {
      std::lock_guard lock(publish_->mutex);
      if (!publish_->rules.add(changed) && !config_.publish_at_once) return;
      now = publish_->rules.take();
    }
    fan_out(std::move(now));
  });
  lod_subscription_ =
      pipeline_.subscribe_lod([this](const pipeline::WorldPipeline::LodPublication& publication) {
        // Pipeline thread: to each session whose layout wants some of the keys, those keys.
        std::vector<std::pair<std::shared_ptr<ClientSession>, pipeline::WorldPipeline::LodKeys>>
            live;
        for (const auto& [owner, keys] : publication.by_owner) {
          if (auto s = sessions_->find(owner); s && s->has_lod_view())
            live.emplace_back(std::move(s), keys);
        }
        for (const auto& [s, keys] : live) s->on_lod_published(keys);
      });
  spdlog::info(
      "voxeld listening on {}:{} (seed {}, max {} players, {} in handshake, {} per address)",
      config_.bind, port_, pipeline_.config().seed, config_.max_clients, config_.max_handshaking,
      config_.max_per_address);
  last_stats_.at = std::chrono::steady_clock::now();
  housekeeping();
  accept();
  start_http();
}

// The HTTP port: an explicit one that cannot be bound stops the start; the default one
// (taken by another program) only leaves the viewer off.
void Server::start_http() {
  if (!config_.http) return;
  http_ = std::make_unique<HttpFront>(io_, *config_.http, counters_, logs_,
                                      [this](WsStream ws, std::string address) {
                                        admit_websocket(std::move(ws), std::move(address));
                                      });
  try {
    http_->start();
  } catch (const boost::system::system_error& e) {
    if (config_.http_port_required) throw;
    spdlog::warn("HTTP port {}:{} not available ({}): no viewer and no WebSocket; set --http-port",
                 config_.http->bind, config_.http->port, e.what());
    http_.reset();
  }
}

void Server::accept() {
  acceptor_.async_accept(
      Strand(io_.get_executor()), [this](boost::system::error_code ec, StrandSocket socket) {
        if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;  // stopped
        if (ec) {
          if (auto suppressed = logs_->allow("accept")) {
            spdlog::warn("accept failed: {} [{} more]", ec.message(), *suppressed);
          }
          // Out of descriptors and the like: try again a little later (at once, the loop
          // would spin on the waiting connection while the condition lasts). A peer's own
          // error passed on by accept does not slow the others.
          if (out_of_resources(ec)) {
            accept_retry_timer_.expires_after(kAcceptRetry);
            accept_retry_timer_.async_wait([this](boost::system::error_code e) {
              if (!e) accept();
            });
            return;
          }
        } else {
          admit(std::move(socket));
        }
        accept();
      });
}

// Admission: handshaking connections have their own cap, each address its own; players
// are counted at Hello (the session asks the gate).
void Server::admit(StrandSocket socket) {
  boost::system::error_code ec;
  const auto peer = socket.remote_endpoint(ec);
  if (ec) return;  // already gone
  const std::vector<std::string>& proxies = config_.tcp_proxies;
  if (std::find(proxies.begin(), proxies.end(), address_text(peer.address())) != proxies.end())
    return read_proxy_header(std::move(socket), peer.address());
  admit_as(std::move(socket), address_key(peer.address()));
}

// The header first, within the handshake timeout, at most as many at once as handshakes;
// a connection without a valid one is closed (logged, rate-limited).
void Server::read_proxy_header(StrandSocket socket, asio::ip::address proxy) {
  if (proxy_reads_.fetch_add(1) >= std::max<size_t>(admission_->limits().max_handshaking, 1)) {
    proxy_reads_.fetch_sub(1);
    return refuse(std::move(socket), AdmissionControl::Verdict::kHandshakesFull);
  }
  struct Read {
    explicit Read(StrandSocket s) : socket(std::move(s)), timer(socket.get_executor()) {}
    StrandSocket socket;
    asio::steady_timer timer;
    std::array<uint8_t, kProxyHeadBytes> head{};
    std::vector<uint8_t> rest;
  };
  auto r = std::make_shared<Read>(std::move(socket));
  const auto fail = [this, r](const std::string& why) {
    proxy_reads_.fetch_sub(1);
    r->timer.cancel();
    boost::system::error_code ignored;
    r->socket.close(ignored);
    if (auto suppressed = logs_->allow("proxy_header")) {
      spdlog::warn("a connection from a trusted proxy closed: {}{}", why,
                   *suppressed ? fmt::format(" [{} more]", *suppressed) : std::string());
    }
  };
  r->timer.expires_after(config_.handshake_timeout);
  r->timer.async_wait([r](boost::system::error_code ec) {
    boost::system::error_code ignored;
    if (!ec) r->socket.close(ignored);  // the reads end with an error
  });
  asio::async_read(
      r->socket, asio::buffer(r->head),
      [this, r, proxy, fail](boost::system::error_code ec, size_t) {
        std::string why;
        const std::optional<size_t> rest = ec ? std::nullopt : proxy_v2_rest(r->head, why);
        if (!rest) return fail(ec ? "no PROXY header in time (" + ec.message() + ")" : why);
        r->rest.resize(*rest);
        asio::async_read(
            r->socket, asio::buffer(r->rest),
            [this, r, proxy, fail](boost::system::error_code ec2, size_t) {
              std::string why2;
              const std::optional<ProxyClient> client =
                  ec2 ? std::nullopt : parse_proxy_v2(r->head, r->rest, why2);
              if (!client)
                return fail(ec2 ? "a PROXY header cut short (" + ec2.message() + ")" : why2);
              proxy_reads_.fetch_sub(1);
              r->timer.cancel();
              admit_as(std::move(r->socket), address_key(client->address.value_or(proxy)));
            });
      });
}

void Server::admit_as(StrandSocket socket, const std::string& address) {
  boost::system::error_code ec;
  const auto verdict = admission_->connect(address);
  if (verdict != AdmissionControl::Verdict::kAdmit) {
    refuse(std::move(socket), verdict);
    return;
  }
  socket.set_option(asio::ip::tcp::no_delay(true), ec);
  auto session = std::make_shared<ClientSession>(
      std::make_unique<TcpConnection>(std::move(socket), shared_config_->max_frame_bytes,
                                      shared_config_->frame_timeout),
      address, next_session_++, pipeline_,
      SessionServices{counters_, shared_config_, admission_, logs_, players_, sessions_, bans_,
                      live_});
  add_session(session);
}

void Server::add_session(const std::shared_ptr<ClientSession>& session) {
  sessions_->add(session->id(), session);
  session->start();
}

// The same admission as TCP; a refused one gets its Error as one message, written without
// waiting, and is closed.
void Server::admit_websocket(WsStream ws, std::string address) {
  const auto verdict = admission_->connect(address);
  if (verdict != AdmissionControl::Verdict::kAdmit) {
    const std::string body = refusal(verdict);
    boost::system::error_code ec;
    auto& socket = boost::beast::get_lowest_layer(ws).socket();
    socket.non_blocking(true, ec);
    ws.binary(true);
    ws.write(asio::buffer(body), ec);
    // Then a close frame, "try again later" (not waited for: the socket does not block).
    if (!ec) ws.close(boost::beast::websocket::close_code::try_again_later, ec);
    socket.close(ec);
    return;
  }
  auto session = std::make_shared<ClientSession>(
      std::make_unique<WsConnection>(std::move(ws), shared_config_->max_frame_bytes,
                                     shared_config_->frame_timeout, counters_),
      std::move(address), next_session_++, pipeline_,
      SessionServices{counters_, shared_config_, admission_, logs_, players_, sessions_, bans_,
                      live_});
  add_session(session);
}

// A refused connection gets one Error frame, written without waiting (a full socket
// buffer just loses it), and is closed at once: it costs no session and no timer.
void Server::refuse(StrandSocket socket, AdmissionControl::Verdict why) {
  const std::string body = refusal(why);
  std::vector<uint8_t> frame;
  proto::append_frame({reinterpret_cast<const uint8_t*>(body.data()), body.size()}, frame);
  boost::system::error_code ec;
  socket.non_blocking(true, ec);
  socket.write_some(asio::buffer(frame), ec);
  socket.close(ec);
}

std::string Server::refusal(AdmissionControl::Verdict why) {
  const bool handshakes = why == AdmissionControl::Verdict::kHandshakesFull;
  ServerCounters::bump(counters_.refused[static_cast<size_t>(
      handshakes ? RefusedBy::kHandshakesFull : RefusedBy::kAddressFull)]);
  ServerCounters::bump(counters_.errors_sent[wire::Error::TOO_MANY_CONNECTIONS]);
  wire::Envelope error;
  error.mutable_error()->set_code(wire::Error::TOO_MANY_CONNECTIONS);
  error.mutable_error()->set_message(handshakes ? "too many connections are in their handshake"
                                                : "too many connections from your address");
  if (auto suppressed = logs_->allow(std::string("refused:") + to_string(why))) {
    spdlog::warn("refusing a connection: {}{}", to_string(why),
                 *suppressed ? fmt::format(" [{} more since the last such line]", *suppressed)
                             : std::string());
  }
  return error.SerializeAsString();
}

void Server::housekeeping() {
  pipeline_.set_session_bytes(counters_.session_bytes.load(std::memory_order_relaxed));
  housekeeping_timer_.expires_after(std::chrono::seconds(1));
  housekeeping_timer_.async_wait([this](boost::system::error_code ec) {
    if (!ec) housekeeping();
  });
}

void Server::stop() {
  asio::post(strand_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    stats_timer_.cancel();
    accept_retry_timer_.cancel();
    housekeeping_timer_.cancel();
  });
  if (http_) http_->stop();
  for (const auto& s : sessions_->live())
    s->close_with_error(wire::Error::SHUTTING_DOWN, "the server is shutting down");
}

// Hands `changed` to every session that may see one of the chunks; each filters exactly
// on its own strand. When the last of them has handled it (or dropped it, closing), the
// list's deleter lets the chunks gathered meanwhile go, from strand_: a gathered fan-out
// runs on a network thread (the first of a quiet spell on the pipeline thread). Any
// thread. The list's deleter and what it posts may outlive the Server: both check
// PublishGate::stopped, set by ~Server, under the gate's mutex.
void Server::fan_out(std::vector<world::ChunkCoord> changed) {
  auto gate = publish_;
  auto shared = std::shared_ptr<const std::vector<world::ChunkCoord>>(
      new std::vector<world::ChunkCoord>(std::move(changed)),
      [this, gate](const std::vector<world::ChunkCoord>* list) {
        delete list;
        std::lock_guard lock(gate->mutex);
        // Once the Server is gone (handlers destroyed with the io_context) nothing goes.
        if (!gate->stopped && gate->rules.handled())
          asio::post(strand_, [this, gate] {
            {  // queued before the Server went: it must not run on a destroyed one
              std::lock_guard lock(gate->mutex);
              if (gate->stopped) return;
            }
            fan_out_gathered();
          });
      });
  for (const auto& s : sessions_->live()) {
    if (s->may_see(*shared)) s->on_chunks_published(shared);
  }
}

void Server::fan_out_gathered() {  // strand_
  std::vector<world::ChunkCoord> changed;
  {
    std::lock_guard lock(publish_->mutex);
    changed = publish_->rules.take();
  }
  fan_out(std::move(changed));
}

size_t Server::session_count() const { return sessions_->count(); }

void Server::start_stats_log(std::chrono::seconds interval) {
  stats_interval_ = interval;
  arm_stats_timer();
}

void Server::arm_stats_timer() {
  stats_timer_.expires_after(stats_interval_);
  stats_timer_.async_wait([this](boost::system::error_code ec) {
    if (ec) return;
    log_stats();
    arm_stats_timer();
  });
}

void Server::log_stats() {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - last_stats_.at).count();
  const Snapshot current{counters_.edits.load(), counters_.meshes_sent.load(),
                         counters_.bytes_sent.load(), now};
  const auto p = pipeline_.stats();
  spdlog::info(
      "stats: {} players, {:.0f} edits/s, {:.0f} meshes sent/s, {:.0f} KiB/s sent, {} chunks "
      "loaded ({} MiB), {} meshes ({} MiB), {} MiB accounted of {} MiB, {} chunks queued",
      counters_.players.load(), static_cast<double>(current.edits - last_stats_.edits) / s,
      static_cast<double>(current.meshes - last_stats_.meshes) / s,
      static_cast<double>(current.bytes - last_stats_.bytes) / s / 1024, p.loaded_chunks,
      p.chunk_bytes >> 20, p.mesh_count, p.mesh_bytes >> 20, p.accounted_bytes >> 20,
      pipeline_.config().max_memory >> 20, p.queued_load_chunks);
  last_stats_ = current;
}

}  // namespace vox::net
