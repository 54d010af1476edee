#include "net/server.hpp"

#include <spdlog/spdlog.h>

namespace vox::net {

Server::Server(asio::io_context& io, ServerConfig config, pipeline::WorldPipeline& pipeline)
    : io_(io), config_(std::move(config)), pipeline_(pipeline), acceptor_(io), stats_timer_(io) {}

Server::~Server() {
  if (subscription_ != 0) pipeline_.unsubscribe(subscription_);
}

void Server::start() {
  const asio::ip::tcp::endpoint endpoint(asio::ip::make_address(config_.bind), config_.port);
  acceptor_.open(endpoint.protocol());
  acceptor_.set_option(asio::ip::tcp::acceptor::reuse_address(true));
  acceptor_.bind(endpoint);
  acceptor_.listen();
  port_ = acceptor_.local_endpoint().port();
  subscription_ = pipeline_.subscribe([this](const std::vector<world::ChunkCoord>& changed) {
    // Pipeline thread: hand the list to every session that may see one of the chunks; each
    // filters exactly on its own strand.
    auto shared = std::make_shared<const std::vector<world::ChunkCoord>>(changed);
    std::vector<std::shared_ptr<ClientSession>> live;
    {
      std::lock_guard lock(sessions_mutex_);
      for (auto it = sessions_.begin(); it != sessions_.end();) {
        if (auto s = it->second.lock()) {
          live.push_back(std::move(s));
          ++it;
        } else {
          it = sessions_.erase(it);
        }
      }
    }
    for (const auto& s : live) {
      if (s->may_see(changed)) s->on_chunks_published(shared);
    }
  });
  spdlog::info("voxeld listening on {}:{} (seed {}, max {} clients)", config_.bind, port_,
               pipeline_.config().seed, config_.max_clients);
  last_stats_.at = std::chrono::steady_clock::now();
  accept();
}

void Server::accept() {
  acceptor_.async_accept(
      asio::make_strand(io_), [this](boost::system::error_code ec, asio::ip::tcp::socket socket) {
        if (ec) {
          if (ec != asio::error::operation_aborted) {
            spdlog::warn("accept failed: {}", ec.message());
            accept();
          }
          return;
        }
        boost::system::error_code ignored;
        socket.set_option(asio::ip::tcp::no_delay(true), ignored);
        auto session = std::make_shared<ClientSession>(std::move(socket), next_session_++, config_,
                                                       pipeline_, counters_);
        size_t count;
        {
          std::lock_guard lock(sessions_mutex_);
          std::erase_if(sessions_, [](const auto& p) { return p.second.expired(); });
          count = sessions_.size();
          if (count < config_.max_clients) sessions_.emplace(session->id(), session);
        }
        session->start();
        if (count >= config_.max_clients) {
          // One line per second at most: a crowd at the door must not flood the log.
          const auto now = std::chrono::steady_clock::now();
          if (now - last_full_warning_ >= std::chrono::seconds(1)) {
            spdlog::warn(
                "refusing a connection: {} clients already (--max-clients); {} more refused since "
                "the last such line",
                count, refused_quietly_);
            last_full_warning_ = now;
            refused_quietly_ = 0;
          } else {
            ++refused_quietly_;
          }
          session->close_with_error(wire::Error::SERVER_FULL, "the server is full");
        }
        accept();
      });
}

void Server::stop() {
  asio::post(io_, [this] {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    stats_timer_.cancel();
  });
  std::vector<std::shared_ptr<ClientSession>> live;
  {
    std::lock_guard lock(sessions_mutex_);
    for (auto& [id, weak] : sessions_)
      if (auto s = weak.lock()) live.push_back(std::move(s));
  }
  for (const auto& s : live)
    s->close_with_error(wire::Error::SHUTTING_DOWN, "the server is shutting down");
}

size_t Server::session_count() const {
  std::lock_guard lock(sessions_mutex_);
  size_t n = 0;
  for (const auto& [id, weak] : sessions_) n += weak.expired() ? 0 : 1;
  return n;
}

void Server::start_stats_log(std::chrono::seconds interval) {
  stats_interval_ = interval;
  stats_timer_.expires_after(stats_interval_);
  stats_timer_.async_wait([this](boost::system::error_code ec) {
    if (ec) return;
    log_stats();
    start_stats_log(stats_interval_);
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
      "loaded ({} MiB), {} meshes ({} MiB)",
      counters_.players.load(), static_cast<double>(current.edits - last_stats_.edits) / s,
      static_cast<double>(current.meshes - last_stats_.meshes) / s,
      static_cast<double>(current.bytes - last_stats_.bytes) / s / 1024, p.loaded_chunks,
      p.chunk_bytes >> 20, p.mesh_count, p.mesh_bytes >> 20);
  last_stats_ = current;
}

}  // namespace vox::net
