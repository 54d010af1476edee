// What a session sends next: per visible chunk the version the client holds, and the
// stale chunks in two queues. Newer versions of chunks the client holds go first (an
// edit's delta never waits behind terrain the client does not have yet), nearest first;
// then chunks new to the client, strictly nearest first: one farther away waits while a
// nearer one is still being loaded (not published), even if it was loaded long ago.
// Pure bookkeeping (no I/O, no threads): the session calls it on its strand, tests call
// it directly.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

#include "server/pipeline/mesh_store.hpp"

namespace vox::net {

class SendScheduler {
 public:
  using Lookup = std::function<pipeline::MeshVersionPtr(world::ChunkCoord)>;

  // The view becomes the chunks within `radius` (Euclidean, chunk units) of `center` (and,
  // given `keep`, for which it is true: a level-of-detail layout's level-0 chunks);
  // every visible chunk is re-checked. Returns the chunks that left the view while the
  // client held a mesh of them (to unload).
  using Keep = std::function<bool(world::ChunkCoord)>;
  std::vector<world::ChunkCoord> set_view(world::ChunkCoord center, int radius,
                                          const Keep& keep = {});
  bool has_view() const { return radius_ >= 0; }
  bool visible(world::ChunkCoord c) const { return visible_.count(c) > 0; }
  size_t visible_count() const { return visible_.size(); }
  size_t stale_count() const {
    return updates_.size() + fresh_.size();
  }  // each visible chunk at most once

  // A newer version of c may exist; ignored unless c is visible.
  void mark_stale(world::ChunkCoord c);
  // The client dropped c (a delta did not apply): its newest version goes again in full,
  // even without triangles, with the updates of held chunks. False when c is not visible.
  bool resync(world::ChunkCoord c);

  // Once per set_view, when every visible chunk has been sent or found empty: how many of
  // each (then the view is complete; nothing until the next set_view).
  struct ViewComplete {
    uint32_t sent = 0, empty = 0;
  };
  std::optional<ViewComplete> take_view_complete();

  struct Send {
    world::ChunkCoord coord;
    pipeline::MeshVersionPtr version;  // what to send (the newest)
    pipeline::MeshVersionPtr base;     // what the client holds (null: send in full)
  };
  // The next stale chunk (see above) whose newest version (from `lookup`) is newer than
  // what the client holds, recorded as held from now on. Chunks not published yet are
  // set aside (they are marked again when published) and hold back farther new ones; a
  // first version without triangles is recorded but not sent. A newest version at or above
  // `first_unsendable` (one that may show an edit whose result the client has not been sent) is
  // deferred until release_deferred(). nullopt when nothing is left.
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
    bool queued = false;               // in updates_ or fresh_
    bool deferred = false;             // in deferred_
    bool waiting = false;              // new to the client, not published yet (in waiting_)
    bool resync = false;               // the client asked for it in full (sent even if empty)
  };
  using Entry = std::pair<int64_t, world::ChunkCoord>;  // distance², chunk
  void queue(world::ChunkCoord c, Held& held);
  std::optional<Send> take(std::vector<Entry>& heap, bool fresh, const Lookup& lookup,
                           uint64_t first_unsendable);
  int64_t nearest_waiting();  // distance² of the nearest waiting chunk (max: none)

  std::unordered_map<world::ChunkCoord, Held, world::ChunkCoordHash> visible_;
  // Min-heaps, nearest first (ties by coordinate); vectors, so marking a chunk stale
  // allocates nothing once warm (a std::set allocated a node per mark). updates_: chunks
  // the client has a version of; fresh_: the others; waiting_: fresh ones not published
  // when their turn came (entries of chunks no longer waiting are skipped lazily).
  std::vector<Entry> updates_, fresh_, waiting_;
  std::vector<world::ChunkCoord> deferred_;  // each visible chunk at most once
  size_t unresolved_ = 0;       // visible chunks with no version recorded (held.version null)
  bool view_announced_ = true;  // take_view_complete() answered for this view
};

}  // namespace vox::net
