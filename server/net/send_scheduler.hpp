// What a session sends next: per visible chunk the version the client holds, and the
// stale chunks ordered nearest first. Pure bookkeeping (no I/O, no threads): the
// session calls it on its strand, tests call it directly.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

#include "pipeline/mesh_store.hpp"

namespace vox::net {

class SendScheduler {
 public:
  using Lookup = std::function<pipeline::MeshVersionPtr(world::ChunkCoord)>;

  // The view becomes the chunks within `radius` (Euclidean, chunk units) of `center`;
  // every visible chunk is re-checked. Returns the chunks that left the view while the
  // client held a mesh of them (to unload).
  std::vector<world::ChunkCoord> set_view(world::ChunkCoord center, int radius);
  bool has_view() const { return radius_ >= 0; }
  bool visible(world::ChunkCoord c) const { return visible_.count(c) > 0; }
  size_t visible_count() const { return visible_.size(); }
  size_t stale_count() const { return stale_.size(); }  // each visible chunk at most once

  // A newer version of c may exist; ignored unless c is visible.
  void mark_stale(world::ChunkCoord c);

  struct Send {
    world::ChunkCoord coord;
    pipeline::MeshVersionPtr version;  // what to send (the newest)
    pipeline::MeshVersionPtr base;     // what the client holds (null: send in full)
  };
  // The nearest stale chunk whose newest version (from `lookup`) is newer than what the
  // client holds, recorded as held from now on. Chunks not published yet are skipped
  // (they are marked again when published); a first version without triangles is
  // recorded but not sent. A newest version at or above `first_unsendable` (one that may
  // show an edit whose result the client has not been sent) is deferred until
  // release_deferred(). nullopt when nothing is left.
  std::optional<Send> next(const Lookup& lookup, uint64_t first_unsendable = UINT64_MAX);
  // Marks the deferred chunks stale again (the limit given to next() has moved).
  void release_deferred();
  size_t deferred_count() const { return deferred_.size(); }

  void clear();

 private:
  int64_t distance2(world::ChunkCoord c) const;

  world::ChunkCoord center_{};
  int radius_ = -1;
  struct Held {
    pipeline::MeshVersionPtr version;  // what the client holds (null: nothing yet)
    bool sent = false;                 // false: an empty first version, never sent
    bool queued = false;               // in stale_
    bool deferred = false;             // in deferred_
  };
  using Entry = std::pair<int64_t, world::ChunkCoord>;  // distance², chunk
  std::unordered_map<world::ChunkCoord, Held, world::ChunkCoordHash> visible_;
  // Min-heap, nearest first (ties by coordinate); a vector, so marking a chunk stale
  // allocates nothing once warm (a std::set allocated a node per mark).
  std::vector<Entry> stale_;
  std::vector<world::ChunkCoord> deferred_;  // each visible chunk at most once
};

}  // namespace vox::net
