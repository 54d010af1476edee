// The session's side of a level-of-detail view (docs/PROTOCOL.md 4.10): a SetView's
// level and distance checked against the limits, and new coarser meshes handed to its
// ViewFeed (view_feed.cpp lays the view out and sends it). Strand only, but where a
// comment says otherwise.
#include <algorithm>
#include <cmath>

#include "server/net/client_session.hpp"

namespace vox::net {

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

void ClientSession::on_lod_published(  // any thread
    std::shared_ptr<const std::vector<pipeline::LodKey>> keys) {
  asio::post(strand_, [self = shared_from_this(), keys = std::move(keys)] {
    if (self->closing_) return;
    if (self->feed_.lod_published(*keys)) self->pump();
  });
}

}  // namespace vox::net
