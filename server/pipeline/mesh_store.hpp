// Published chunk meshes: immutable, versioned records shared by pointer. The pipeline
// replaces a chunk's record; readers copy the pointer under a short shard lock (no I/O
// while held) and then read the record without any lock.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "mesh/chunk_mesh.hpp"
#include "world/chunk_coord.hpp"

namespace vox::pipeline {

struct MeshVersion {
  world::ChunkCoord coord;
  uint64_t version = 0;  // increases with every publication (so also per chunk)
  mesh::ChunkMesh mesh;  // chunk-local positions
  size_t memory_bytes() const;
};
using MeshVersionPtr = std::shared_ptr<const MeshVersion>;

class MeshStore {
 public:
  MeshVersionPtr get(world::ChunkCoord c) const;  // any thread; null when none published
  void publish(MeshVersionPtr mesh);             // pipeline thread
  void erase(world::ChunkCoord c);               // pipeline thread
  size_t size() const { return count_.load(std::memory_order_relaxed); }
  size_t memory_bytes() const { return bytes_.load(std::memory_order_relaxed); }

 private:
  static constexpr size_t kShards = 64;
  struct Shard {
    mutable std::mutex mutex;  // leaf lock: nothing else is locked while it is held
    std::unordered_map<world::ChunkCoord, MeshVersionPtr, world::ChunkCoordHash> meshes;
  };
  Shard& shard(world::ChunkCoord c) const { return shards_[world::ChunkCoordHash{}(c) % kShards]; }

  mutable std::array<Shard, kShards> shards_;
  std::atomic<size_t> count_{0}, bytes_{0};
};

}  // namespace vox::pipeline
