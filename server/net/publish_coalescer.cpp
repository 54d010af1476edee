#include "server/net/publish_coalescer.hpp"

#include <algorithm>

namespace vox::net {

namespace {
void sort_unique(std::vector<world::ChunkCoord>& v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}
}  // namespace

bool PublishCoalescer::add(const std::vector<world::ChunkCoord>& chunks) {
  pending_.insert(pending_.end(), chunks.begin(), chunks.end());
  if (pending_.size() >= std::max(kCompactAt, 2 * compacted_)) {
    sort_unique(pending_);
    compacted_ = pending_.size();
  }
  if (in_flight_) return false;
  in_flight_ = true;
  return true;
}

bool PublishCoalescer::handled() {
  in_flight_ = !pending_.empty();
  return in_flight_;
}

std::vector<world::ChunkCoord> PublishCoalescer::take() {
  std::vector<world::ChunkCoord> out;
  out.swap(pending_);
  sort_unique(out);
  compacted_ = 0;
  return out;
}

}  // namespace vox::net
