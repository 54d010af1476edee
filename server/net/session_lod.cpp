// The session's level-of-detail view (docs/PROTOCOL.md 4.10): its layout as the
// player moves, the level-0 chunks of it (sent by the SendScheduler like any view), the
// coarser chunks (LodSendQueue), their unloads and messages. Strand only, but where a
// comment says otherwise.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "server/net/client_session.hpp"
#include "server/net/wire_convert.hpp"

namespace vox::net {

using world::ChunkCoord;
using world::LodChunk;

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

// The layout: levels 0 .. lod_level, the 3x3x3 top-level chunks around the eye; level-1
// chunks split within about `radius` chunks (so level 0 reaches that far), coarser ones
// within lod_distance of their side. Returns the radius of the ball holding every level-0
// chunk of the layout, and in `keep` which of the ball's chunks those are.
int ClientSession::apply_lod_view(const PendingView& v, std::function<bool(ChunkCoord)>& keep) {
  const world::LodSettings settings{.levels = v.lod_level + 1,
                                    .top_radius = 1,
                                    .split_distance = v.lod_distance,
                                    .near_split_distance = std::max(0.5, v.radius / 2.0)};
  const bool same = lod_view_ && lod_settings_.levels == settings.levels &&
                    lod_settings_.split_distance == settings.split_distance &&
                    lod_settings_.near_split_distance == settings.near_split_distance;
  if (!same) {
    drop_lod_view();
    lod_view_.emplace(settings);
    lod_settings_ = settings;
  }
  const world::LodViewChange change = lod_view_->update(v.eye);  // eye checked: finite, bounded
  queue_lod_unload(lod_queue_.apply(change, v.eye));
  if (!change.empty() || !lod_level0_) {
    // The layout changed: its level-0 chunks and the pipeline's wants with it (a walking
    // player's SetViews mostly leave the layout as it was).
    auto level0 = std::make_shared<std::unordered_set<ChunkCoord, world::ChunkCoordHash>>();
    for (const LodChunk& c : lod_view_->layout().chunks())
      if (c.level == 0) level0->insert(c.c);
    lod_level0_ = std::move(level0);
    pipeline_.set_lod_view(id_, lod_queue_.wants());
  }
  int64_t r2 = 0;
  for (const ChunkCoord c : *lod_level0_) {
    const int64_t dx = c.x - v.center.x, dy = c.y - v.center.y, dz = c.z - v.center.z;
    r2 = std::max(r2, dx * dx + dy * dy + dz * dz);
  }
  keep = [level0 = lod_level0_](ChunkCoord c) { return level0->count(c) > 0; };
  lod_active_.store(true, std::memory_order_relaxed);
  return static_cast<int>(std::ceil(std::sqrt(static_cast<double>(r2))));
}

void ClientSession::drop_lod_view() {
  if (!lod_view_) return;
  std::vector<LodChunk> held;
  for (const auto& [c, seams] : lod_view_->held()) held.push_back(c);
  std::sort(held.begin(), held.end());  // the same ChunkUnloads whatever the map's order
  world::LodViewChange gone;
  gone.unload = held;
  queue_lod_unload(lod_queue_.apply(gone, {}));
  lod_queue_.clear();
  lod_view_.reset();
  lod_level0_.reset();
  lod_active_.store(false, std::memory_order_relaxed);
  pipeline_.set_lod_view(id_, {});
}

// One ChunkUnload per level.
void ClientSession::queue_lod_unload(const std::vector<LodChunk>& chunks) {
  std::map<int, wire::Envelope> by_level;
  for (const LodChunk& c : chunks) {
    auto* u = by_level[c.level].mutable_chunk_unload();
    u->set_level(static_cast<uint32_t>(c.level));
    *u->add_coords() = to_wire(c.c);
  }
  for (const auto& [level, message] : by_level) queue_control(message);
}

bool ClientSession::append_next_lod_mesh() {
  if (!lod_view_) return false;
  const auto send =
      lod_queue_.next([this](const pipeline::LodKey& k) { return pipeline_.lod_meshes().get(k); });
  if (!send) return false;
  auto* m = mesh_message_.mutable_chunk_mesh();
  *m->mutable_coord() = to_wire(send->chunk.c);
  m->set_level(static_cast<uint32_t>(send->chunk.level));
  m->set_version(send->wire_version);
  if (send->base) {
    const auto delta = send->version->delta_from(*send->base);
    m->set_base_version(send->wire_base);
    m->set_payload(delta->data(), delta->size());
    counters_.deltas_sent.fetch_add(1, std::memory_order_relaxed);
  } else {
    m->set_base_version(0);
    const std::span<const uint8_t> full = send->version->full();
    m->set_payload(full.data(), full.size());
  }
  connection_->append(mesh_message_);
  m->set_level(0);  // the message is reused for level-0 meshes
  counters_.meshes_sent.fetch_add(1, std::memory_order_relaxed);
  return true;
}

void ClientSession::on_lod_published(  // any thread
    std::shared_ptr<const std::vector<pipeline::LodKey>> keys) {
  asio::post(strand_, [self = shared_from_this(), keys = std::move(keys)] {
    if (self->closing_ || !self->lod_view_) return;
    for (const pipeline::LodKey& k : *keys) self->lod_queue_.mark_stale(k);
    self->pump();
  });
}

}  // namespace vox::net
