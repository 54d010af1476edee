#include "loadtest/sim_player.hpp"

#include <cmath>
#include <numbers>

namespace vox::loadtest {

namespace asio = boost::asio;
using client::ChunkKey;

namespace {
constexpr double kTickS = 0.05;
constexpr double kPingEveryS = 10;
// The first view is complete after this long without a full mesh.
// Waiting for a changed chunk whose mesh never came (e.g. it stayed empty) ends after this.
constexpr double kDeltaGiveUpS = 10;

// Decoding scratch per event-loop thread (players on one thread never decode at once).
struct DecodeScratch {
  proto::ZstdCodec zstd;
  proto::CodecScratch scratch;
  mesh::ChunkMesh decoded;
  mesh::Buffer<uint8_t> expanded;
};
DecodeScratch& decode_scratch() {
  thread_local DecodeScratch scratch;
  return scratch;
}

std::string status_name(int status) {
  const std::string& name = wire::EditResult::Status_Name(status);
  return name.empty() ? "status " + std::to_string(status) : name;
}

std::vector<uint8_t> bytes_of(const wire::Envelope& m) {
  std::vector<uint8_t> out(m.ByteSizeLong());
  m.SerializeWithCachedSizesToArray(out.data());
  return out;
}

// Where player `id` connects first: the i mod (1 + n)-th of host:port and more_servers.
size_t first_server(const LoadConfig& c, int id) {
  return c.ws_port != 0 ? 0 : static_cast<size_t>(id) % (1 + c.more_servers.size());
}

// Where player `id` connects: --websocket's HTTP port or the TCP port of `server`, from its
// own loopback address with --spread-addresses.
LinkTarget target_of(const LoadConfig& c, int id, size_t server) {
  const bool ws = c.ws_port != 0;
  return {.host = ws            ? c.ws_host
                  : server == 0 ? c.host
                                : c.more_servers[server - 1].first,
          .port = ws            ? c.ws_port
                  : server == 0 ? c.port
                                : c.more_servers[server - 1].second,
          .source = c.spread_addresses ? spread_source_address(0, id) : std::string(),
          .websocket = ws};
}
}  // namespace

SimPlayer::SimPlayer(LoadTest& test, int id, uint32_t seed)
    : test_(test),
      id_(id),
      rng_(seed),
      strand_(asio::make_strand(test.io())),
      link_(
          make_player_link(strand_, target_of(test.config(), id, first_server(test.config(), id)))),
      timer_(strand_),
      retry_timer_(strand_),
      server_(first_server(test.config(), id)) {
  const auto half_width = static_cast<float>(test.half_width());
  std::uniform_real_distribution<float> spawn(-half_width, half_width);
  x_ = spawn(rng_);
  z_ = spawn(rng_);
  heading_ = std::uniform_real_distribution<float>(0, 2 * std::numbers::pi_v<float>)(rng_);
  radius_ = test.config().view_radius;
  publish_position();
}

void SimPlayer::publish_position() {
  published_[0].store(x_, std::memory_order_relaxed);
  published_[1].store(y_, std::memory_order_relaxed);
  published_[2].store(z_, std::memory_order_relaxed);
}

std::array<float, 3> SimPlayer::position() const {
  return {published_[0].load(std::memory_order_relaxed),
          published_[1].load(std::memory_order_relaxed),
          published_[2].load(std::memory_order_relaxed)};
}

void SimPlayer::start() {
  asio::dispatch(strand_, [self = shared_from_this()] { self->connect(); });
}

void SimPlayer::connect() {
  link_->connect([self = shared_from_this(), gen = link_gen_](const std::string& error) {
    if (gen != self->link_gen_) return;  // a link given up for another
    if (!error.empty()) {
      self->fail(error, true);
      return;
    }
    wire::Envelope hello;
    hello.mutable_hello()->set_protocol_version(1);
    hello.mutable_hello()->set_player_name("sim" + std::to_string(self->id_));
    const std::string& token = self->test_.player_token(self->id_);
    if (!token.empty()) hello.mutable_hello()->set_token(token);
    self->send(hello);
    self->read_more();
  });
}

void SimPlayer::close() {
  closed_ = true;
  gone_.store(true, std::memory_order_release);
  timer_.cancel();
  retry_timer_.cancel();
  link_->close();
}

void SimPlayer::fail(const std::string& cause, bool disconnect) {
  if (closed_) return;
  if (!disconnect) {
    test_.record_error(cause);
    return;
  }
  test_.record_disconnect(cause);
  if (test_.config().reconnect && !test_.stopping()) {
    reconnect();
  } else {
    close();
  }
}

// The connection closed (its node died, say): the next server, after a moment (one that
// refuses at once must not make this spin), with a fresh link and nothing held (the server
// sends full copies of the view again).
void SimPlayer::reconnect() {
  link_->close();
  ++link_gen_;
  welcomed_ = writing_ = false;
  outbox_.clear();
  cache_ = client::ChunkCache();
  lod_cache_.clear();
  // Edits answered but waiting for their deltas: those deltas come as full copies now.
  std::erase_if(pending_, [](const auto& p) { return p.second.have_result; });
  if (lost_s_ < 0) lost_s_ = test_.now_s();
  server_ = (server_ + 1) % (1 + test_.config().more_servers.size());
  link_ = make_player_link(strand_, target_of(test_.config(), id_, server_));
  retry_timer_.expires_after(std::chrono::milliseconds(100));
  retry_timer_.async_wait(
      [self = shared_from_this(), gen = link_gen_](boost::system::error_code ec) {
        if (!ec && gen == self->link_gen_ && !self->closed_) self->connect();
      });
}

void SimPlayer::send(const wire::Envelope& m) {
  if (closed_) return;
  outbox_.push_back(bytes_of(m));
  write_more();
}

void SimPlayer::write_more() {
  if (writing_ || outbox_.empty() || closed_) return;
  writing_ = true;
  link_->write(outbox_.front(),
               [self = shared_from_this(), gen = link_gen_](const std::string& error) {
                 if (gen != self->link_gen_) return;
                 self->writing_ = false;
                 if (!error.empty()) {
                   if (!self->test_.stopping()) self->fail(error, true);
                   return;
                 }
                 self->outbox_.pop_front();
                 self->write_more();
               });
}

void SimPlayer::read_more() {
  link_->read([self = shared_from_this(), gen = link_gen_](const std::string& error, size_t n) {
    if (gen != self->link_gen_) return;
    if (!error.empty()) {
      if (!self->closed_ && !self->test_.stopping()) self->fail(error, true);
      return;
    }
    self->test_.count_bytes(n);
    while (auto bytes = self->link_->next_message()) {
      wire::Envelope m;
      if (!m.ParseFromArray(bytes->data(), static_cast<int>(bytes->size()))) {
        self->fail("unparsable message from the server", true);
        return;
      }
      self->test_.count_message();
      self->on_message(m);
      if (self->closed_) return;
    }
    if (!self->link_->message_error().empty()) {
      self->fail(self->link_->message_error(), true);
      return;
    }
    self->read_more();
  });
}

bool SimPlayer::in_view(const ChunkKey& k) const {
  // A LOD view's level 0 is its layout's level-0 chunks: those the player holds.
  if (test_.config().lod_level > 0) return cache_.chunks().count(k) > 0;
  const int64_t dx = std::get<0>(k) - std::get<0>(view_chunk_),
                dy = std::get<1>(k) - std::get<1>(view_chunk_),
                dz = std::get<2>(k) - std::get<2>(view_chunk_);
  return dx * dx + dy * dy + dz * dz <= static_cast<int64_t>(radius_) * radius_;
}

void SimPlayer::on_message(const wire::Envelope& m) {
  switch (m.body_case()) {
    case wire::Envelope::kWelcome:
      welcomed_ = true;
      if (!test_.set_world_seed(m.welcome().world_seed()))
        fail("Welcome with a different world seed", false);
      if (lost_s_ >= 0) {  // connected again (--reconnect)
        test_.record_reconnect((test_.now_s() - lost_s_) * 1000);
        awaiting_view_ = true;
        send_view();
        for (auto& [request, p] : pending_) {  // unanswered: again, with its edit id
          send(p.edit);
          test_.record_resent();
        }
        break;
      }
      test_.record_connected();
      y_ = test_.terrain_height(x_, z_);
      publish_position();
      send_view();
      next_edit_s_ =
          test_.now_s() + std::exponential_distribution<double>(test_.config().edit_rate)(rng_);
      last_tick_s_ = test_.now_s();
      if (!ticking_) {
        ticking_ = true;
        tick();
      }
      break;
    case wire::Envelope::kChunkMesh:
      on_chunk_mesh(m.chunk_mesh());
      break;
    case wire::Envelope::kChunkUnload:
      if (m.chunk_unload().level() > 0) {
        lod_cache_[m.chunk_unload().level()].forget(m.chunk_unload());
        break;
      }
      cache_.forget(m.chunk_unload());
      for (auto& [id, p] : pending_) {
        for (const auto& c : m.chunk_unload().coords()) p.waiting.erase({c.x(), c.y(), c.z()});
      }
      break;
    case wire::Envelope::kEditResult: {
      const auto& r = m.edit_result();
      auto it = pending_.find(r.request_id());
      if (it == pending_.end()) {
        fail("EditResult for an unknown request", false);
        break;
      }
      // RATE_LIMITED and SERVER_BUSY are refusals like the others: an honest player does
      // not retry, so a limit that hits honest players shows as refused edits.
      test_.record_result(
          it->second.sent_s, test_.now_s(),
          r.status() == wire::EditResult::ACCEPTED ? std::string() : status_name(r.status()));
      it->second.have_result = true;
      if (r.already_applied()) test_.record_already_applied();
      for (const auto& c : r.changed_chunks()) {
        const ChunkKey k = client::key_of(c);
        if (in_view(k)) it->second.waiting.insert(k);
      }
      if (it->second.waiting.empty()) pending_.erase(it);  // nothing visible changed
      break;
    }
    case wire::Envelope::kError:
      if (m.error().code() == wire::Error::SHUTTING_DOWN && test_.stopping()) break;
      fail("Error " + wire::Error::Code_Name(m.error().code()), false);
      break;
    case wire::Envelope::kViewReady:
      ready_view_.store(m.view_ready().view_id(), std::memory_order_release);
      if (awaiting_view_ &&
          m.view_ready().view_id() == views_sent_.load(std::memory_order_relaxed)) {
        test_.record_reconnect_view((test_.now_s() - lost_s_) * 1000);
        awaiting_view_ = false;
        lost_s_ = -1;
      }
      if (!first_view_done_) {  // the first view the server completed (the player may have moved)
        first_view_done_ = true;
        test_.record_first_view((test_.now_s() - view_sent_s_) * 1000);
      }
      break;
    default:
      break;  // Pong
  }
}

void SimPlayer::on_chunk_mesh(const wire::ChunkMesh& m) {
  test_.count_chunk();
  if (auto error = apply_mesh(m)) {
    test_.count_decode_failure();
    fail("decode failure: " + *error, false);
    return;
  }
  if (m.level() > 0) return;  // edit -> delta is measured on level 0
  const double now = test_.now_s();
  const ChunkKey k = client::key_of(m.coord());
  for (auto it = pending_.begin(); it != pending_.end();) {
    PendingEdit& p = it->second;
    if (p.have_result && p.waiting.erase(k) && p.waiting.empty()) {
      test_.record_delta(p.sent_s, now);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
}

// Expands the payload against the held base and decodes it, unless the expanded bytes
// are an encoding another player already decoded (DecodeMemo).
std::optional<std::string> SimPlayer::apply_mesh(const wire::ChunkMesh& m) {
  if (m.level() > 20) return "a chunk of level " + std::to_string(m.level());
  DecodeScratch& d = decode_scratch();
  client::ChunkCache& cache = m.level() == 0 ? cache_ : lod_cache_[m.level()];
  if (auto error = cache.expand(m, d.zstd, d.expanded)) return error;
  const std::span<const uint8_t> encoding(d.expanded.data(), d.expanded.size());
  const MemoKey key{m.level(), client::key_of(m.coord())};
  DecodeMemo* memo = test_.decode_memo();
  if (!memo || !memo->known_good(key, encoding)) {
    if (auto error = proto::decode_mesh(encoding, {}, d.scratch, d.decoded)) {
      cache.drop(key.chunk);
      return error->message;
    }
    if (memo) memo->remember(key, encoding);
  }
  cache.hold(key.chunk, m.version(), encoding);
  return std::nullopt;
}

void SimPlayer::send_view() {
  view_chunk_ =
      client::chunk_of_voxel(static_cast<int>(std::floor(x_)), static_cast<int>(std::floor(y_)),
                             static_cast<int>(std::floor(z_)));
  wire::Envelope v;
  v.mutable_set_view()->mutable_position()->set_x(x_);
  v.mutable_set_view()->mutable_position()->set_y(y_);
  v.mutable_set_view()->mutable_position()->set_z(z_);
  v.mutable_set_view()->set_radius(radius_);
  v.mutable_set_view()->set_lod_level(test_.config().lod_level);
  if (test_.config().lod_level > 0)
    v.mutable_set_view()->set_lod_distance(test_.config().lod_distance);
  v.mutable_set_view()->set_view_id(views_sent_.load(std::memory_order_relaxed) + 1);
  views_sent_.fetch_add(1, std::memory_order_release);
  view_position_ = {x_, y_, z_};
  send(v);
  if (view_sent_s_ < 0) view_sent_s_ = test_.now_s();
}

void SimPlayer::send_edit() {
  std::uniform_real_distribution<float> unit(0, 1);
  std::array<float, 3> target{x_, y_, z_};
  if (unit(rng_) < 0.3f) target = test_.someone_elses_position(id_, rng_);
  target[0] += (unit(rng_) - 0.5f) * 16;
  target[2] += (unit(rng_) - 0.5f) * 16;
  target[1] = test_.terrain_height(target[0], target[2]);
  wire::Envelope m;
  auto* e = m.mutable_edit();
  const uint64_t request = next_request_++;
  e->set_request_id(request);
  if (test_.config().reconnect) e->set_edit_id(request);  // the same id when sent again
  wire::Vec3* centre;
  if (unit(rng_) < 0.8f) {
    auto* b = e->mutable_brush();
    b->set_radius(3);
    b->set_strength(0.6f);
    b->set_remove(unit(rng_) < 0.5f);
    centre = b->mutable_center();
  } else {
    auto* x = e->mutable_explosion();
    x->set_radius(5);
    x->set_power(1.5f);
    centre = x->mutable_center();
  }
  centre->set_x(target[0]);
  centre->set_y(target[1]);
  centre->set_z(target[2]);
  pending_[request] = {test_.now_s(), false, {}, test_.config().reconnect ? m : wire::Envelope()};
  test_.record_edit_sent();
  send(m);
}

// Keep a heading, turn now and then, stay near the spawn area; a new chunk is a new view.
void SimPlayer::walk(double dt) {
  std::uniform_real_distribution<float> unit(0, 1);
  if (unit(rng_) < 0.02f) heading_ += (unit(rng_) - 0.5f) * 2.0f;
  const float limit = static_cast<float>(test_.half_width()) * 1.5f;
  if (std::fabs(x_) > limit || std::fabs(z_) > limit) heading_ = std::atan2(-z_, -x_);
  const auto step = static_cast<float>(test_.config().walk_speed * dt);
  x_ += std::cos(heading_) * step;
  z_ += std::sin(heading_) * step;
  y_ = test_.terrain_height(x_, z_);
  publish_position();
  const client::ChunkKey chunk =
      client::chunk_of_voxel(static_cast<int>(std::floor(x_)), static_cast<int>(std::floor(y_)),
                             static_cast<int>(std::floor(z_)));
  if (chunk != view_chunk_) send_view();
}

void SimPlayer::tick() {
  if (closed_) return;
  const double now = test_.now_s();
  const double dt = now - last_tick_s_;
  last_tick_s_ = now;
  // Once the editing stops, players stand still so that every view can complete for the
  // verification.
  if (test_.editing() && welcomed_) walk(dt);
  if (test_.editing() && welcomed_ && now >= next_edit_s_) {
    send_edit();
    next_edit_s_ = now + std::exponential_distribution<double>(test_.config().edit_rate)(rng_);
  }
  if (welcomed_ && now - last_ping_s_ > kPingEveryS) {
    wire::Envelope ping;
    ping.mutable_ping()->set_nonce(static_cast<uint64_t>(now * 1000));
    send(ping);
    last_ping_s_ = now;
  }
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (now - it->second.sent_s <= kDeltaGiveUpS) {
      ++it;
      continue;
    }
    // No result in time is an error; a changed chunk whose mesh never came (it stayed
    // without triangles, so nothing was sent) is not.
    if (!it->second.have_result) fail("no EditResult within 10 s", false);
    it = pending_.erase(it);
  }
  timer_.expires_after(std::chrono::milliseconds(static_cast<int>(kTickS * 1000)));
  timer_.async_wait([self = shared_from_this()](boost::system::error_code ec) {
    if (!ec) self->tick();
  });
}

}  // namespace vox::loadtest
