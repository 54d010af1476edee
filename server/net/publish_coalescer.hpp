// When the sessions hear of published chunks. Each publication fanned out at once made
// every session that sees it handle it and write on its own: at 1,000 players about 90
// batches a second each woke some 700 sessions, and the network thread spent 40 % of its
// time in sendto (docs/PERFORMANCE.md, issue 39). Now one fan-out is in flight at a time:
// a publication goes at once when the last fan-out has been handled by every session it
// told, and otherwise waits, gathered with the next ones, until it has; then they go as
// one (each chunk once). The window is the network threads' own backlog: an idle server
// adds no delay, a busy one tells each session once per turn of its queue (a fixed 20 ms
// interval cost 500 players 13 ms of edit->delta p50 and more at p99).
// Pure bookkeeping (no I/O, no threads): the Server guards it with a mutex; tests call it
// directly.
#pragma once

#include <vector>

#include "server/world/chunk_coord.hpp"

namespace vox::net {

class PublishCoalescer {
 public:
  // Chunks published. True: they go now (take() and fan out); false: gathered until the
  // fan-out in flight is handled.
  bool add(const std::vector<world::ChunkCoord>& chunks);
  // Every session the fan-out in flight told has handled it. True: gathered chunks go now
  // (take() and fan out).
  bool handled();
  // The gathered chunks, each once (sorted), for the fan-out now in flight.
  std::vector<world::ChunkCoord> take();
  bool in_flight() const { return in_flight_; }
  size_t pending() const { return pending_.size(); }

 private:
  // Between two fan-outs the list is deduplicated once it passes this size, so it stays
  // within the chunks in memory however long a fan-out takes to be handled.
  static constexpr size_t kCompactAt = 4096;
  bool in_flight_ = false;
  size_t compacted_ = 0;  // pending_'s size after its last deduplication
  std::vector<world::ChunkCoord> pending_;
};

}  // namespace vox::net
