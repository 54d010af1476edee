// What a session sends next of its level-of-detail chunks (levels >= 1): per
// chunk of the client's layout the seams it needs and the version it holds; stale chunks
// nearest first (finer first between equals). A chunk whose seams changed gets the new
// variant as a delta from the one it holds. Wire versions are the session's own, one
// counter for all its LOD chunks, so every chunk's versions increase whatever variant
// (each meshed at its own time) it is sent. Pure bookkeeping: the session calls it on its
// strand, tests call it directly.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

#include "server/pipeline/lod_mesh_store.hpp"
#include "server/world/lod_view.hpp"

namespace vox::net {

class LodSendQueue {
 public:
  using Lookup = std::function<pipeline::MeshVersionPtr(const pipeline::LodKey&)>;

  // The client's layout changed (LodView::update; or not: an empty change) around `eye`;
  // the queued chunks are re-ordered. Returns the chunks that left it while the client held a mesh
  // of them.
  std::vector<world::LodChunk> apply(const world::LodViewChange& change,
                                     const std::array<double, 3>& eye);
  // A new version of `k` was published; ignored unless the client's layout has that
  // chunk with those seams.
  void mark_stale(const pipeline::LodKey& k);
  // The client dropped `c`: its newest version goes again in full. False when not held.
  bool resync(const world::LodChunk& c);
  // What the pipeline must mesh for this client: every chunk with its seams, nearest first.
  std::vector<pipeline::LodKey> wants() const;
  bool holds(const world::LodChunk& c) const { return chunks_.count(c) > 0; }
  size_t size() const { return chunks_.size(); }

  struct Send {
    world::LodChunk chunk;
    pipeline::MeshVersionPtr version;  // to send
    pipeline::MeshVersionPtr base;     // what the client holds (null: in full)
    uint64_t wire_version = 0, wire_base = 0;
  };
  // The nearest stale chunk whose newest version differs from what the client holds,
  // recorded as held; a chunk not meshed yet waits for mark_stale(); a first version
  // without triangles is recorded, not sent. nullopt when nothing is left.
  std::optional<Send> next(const Lookup& lookup);

  // Once after each apply(), when every chunk of the layout has been sent, with the seams
  // it needs now, or found empty.
  struct Complete {
    uint32_t sent = 0, empty = 0;
  };
  std::optional<Complete> take_complete();
  bool complete() const { return unresolved_ == 0; }
  void clear();

 private:
  struct Held {
    world::LodSeams seams;             // wanted
    pipeline::MeshVersionPtr version;  // recorded (null: nothing yet)
    world::LodSeams version_seams;     // the seams of `version`
    uint64_t wire_version = 0;         // of the mesh the client holds (0: none)
    double distance = 0;
    bool sent = false, queued = false, resync = false;
  };
  using Entry = std::pair<std::pair<double, int>, world::LodChunk>;  // (distance, level), chunk
  void queue(const world::LodChunk& c, Held& h);
  // The client holds (or was found empty) the mesh of the seams it needs now.
  static bool resolved(const Held& h);

  std::unordered_map<world::LodChunk, Held, world::LodChunkHash> chunks_;
  std::vector<Entry> heap_;  // min-heap; entries of chunks no longer queued are skipped
  std::array<double, 3> eye_{};
  uint64_t next_wire_version_ = 1;
  size_t unresolved_ = 0;  // chunks not resolved()
  bool announced_ = true;
};

}  // namespace vox::net
