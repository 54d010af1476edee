// Published chunk meshes: immutable, versioned records shared by pointer. The pipeline
// replaces a chunk's record; readers copy the pointer under a short shard lock (no I/O
// while held) and then read the record without any lock.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <unordered_map>
#include <vector>

#include "server/world/chunk_coord.hpp"

namespace vox::proto {
class ZstdCodec;
}

namespace vox::pipeline {

struct MeshVersion {
  world::ChunkCoord coord;
  uint64_t version = 0;  // increases with every publication (so also per chunk)
  // The mesh's triangles; the mesh itself is not kept (its encoding is: 1,000 players' level-0
  // meshes kept as floats and indices were 180 MiB besides their encodings).
  uint32_t triangles = 0;
  std::vector<uint8_t> encoding;  // the wire encoding (docs/PROTOCOL.md section 2)
  // zstd frame of `encoding` (a full ChunkMesh payload), made at publication when the chunk
  // had no version before; else left empty for full() to make on first request.
  std::vector<uint8_t> full_frame;
  // When the oldest edit this version shows was submitted to the pipeline; the epoch when
  // no edit made it (a load). Sessions measure edit -> delta written from it.
  std::chrono::steady_clock::time_point edited_at{};
  size_t memory_bytes() const;  // without the delta cache (the store accounts it apart)
  MeshVersion() = default;
  ~MeshVersion();  // gives the delta cache's bytes back to the store's account

  // The delta payload that turns `base` (an older version of this chunk) into this one:
  // premade (premake_delta) or computed on first request, then shared by every client
  // holding the same base. Any thread.
  std::shared_ptr<const std::vector<uint8_t>> delta_from(const MeshVersion& base) const;
  // Before publication (the pipeline thread or its meshing workers): the delta from `base`
  // made now, so the network thread, which would make it for the first client asking,
  // only sends it (issue 39: making deltas was a tenth of its time at 1,000 players).
  // `base` is published (its version set).
  void premake_delta(const MeshVersion& base, proto::ZstdCodec& zstd);
  // The full ChunkMesh payload: full_frame, or made on first request and kept (a re-mesh:
  // the clients holding the chunk take deltas, and most re-meshes never need one; its
  // bytes count with the deltas'). Valid while this version lives. Any thread.
  std::span<const uint8_t> full() const;

 private:
  friend class MeshStore;
  friend class LodMeshStore;
  mutable std::mutex deltas_mutex_;  // leaf lock; compression runs outside it
  mutable std::vector<std::pair<uint64_t, std::shared_ptr<const std::vector<uint8_t>>>> deltas_;
  mutable std::unique_ptr<const std::vector<uint8_t>> lazy_full_;  // set once, under deltas_mutex_
  mutable size_t full_accounted_ = 0;  // its bytes added to delta_account_ (0: not published yet)
  // The store's count of delta bytes (set when published; shared, as a version may
  // outlive the store in a session's hands).
  mutable std::shared_ptr<std::atomic<size_t>> delta_account_;
  // On publication, by either store: the store's account, with the premade deltas' bytes
  // added to it (the destructor takes every delta's bytes back off it).
  void attach_account(std::shared_ptr<std::atomic<size_t>> account) const;
};
using MeshVersionPtr = std::shared_ptr<const MeshVersion>;

class MeshStore {
 public:
  MeshVersionPtr get(world::ChunkCoord c) const;  // any thread; null when none published
  void publish(MeshVersionPtr mesh);              // pipeline thread
  void erase(world::ChunkCoord c);                // pipeline thread
  size_t size() const { return count_.load(std::memory_order_relaxed); }
  // Published meshes with their encodings and cached deltas (also of versions already
  // replaced that sessions still hold).
  size_t memory_bytes() const {
    return bytes_.load(std::memory_order_relaxed) + delta_bytes_->load(std::memory_order_relaxed);
  }
  // The highest version published so far (any thread). Versions only grow, so every
  // version published after this call returns is greater.
  uint64_t newest_version() const { return newest_.load(std::memory_order_acquire); }

 private:
  static constexpr size_t kShards = 64;
  struct Shard {
    mutable std::mutex mutex;  // leaf lock: nothing else is locked while it is held
    std::unordered_map<world::ChunkCoord, MeshVersionPtr, world::ChunkCoordHash> meshes;
  };
  Shard& shard(world::ChunkCoord c) const { return shards_[world::ChunkCoordHash{}(c) % kShards]; }

  mutable std::array<Shard, kShards> shards_;
  std::atomic<size_t> count_{0}, bytes_{0};
  std::atomic<uint64_t> newest_{0};
  std::shared_ptr<std::atomic<size_t>> delta_bytes_ = std::make_shared<std::atomic<size_t>>(0);
};

}  // namespace vox::pipeline
