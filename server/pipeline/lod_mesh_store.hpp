// Published level-of-detail meshes: per (level-k chunk, seams) the newest
// immutable MeshVersion, shared by every client whose layout needs that chunk with those
// seams. The pipeline thread publishes and erases (a key leaves when no client's layout
// uses it any more); readers copy the pointer under a short lock and read the record
// without one. A chunk with no surface has a version too (an empty mesh): it is resolved.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "server/pipeline/mesh_store.hpp"
#include "server/world/lod_layout.hpp"

namespace vox::pipeline {

struct LodKey {
  world::LodChunk chunk;
  world::LodSeams seams;  // normalized (lod_seams.hpp)
  friend bool operator==(const LodKey&, const LodKey&) = default;
};

struct LodKeyHash {
  size_t operator()(const LodKey& k) const {
    uint64_t h = world::ChunkCoordHash{}(k.chunk.c);
    h ^= (static_cast<uint64_t>(k.chunk.level) << 40) ^ (uint64_t{k.seams.faces} << 48) ^
         (uint64_t{k.seams.edges} << 20);
    h *= 0x9E3779B97F4A7C15ull;
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

class LodMeshStore {
 public:
  MeshVersionPtr get(const LodKey& k) const;           // any thread; null when none published
  void publish(const LodKey& k, MeshVersionPtr mesh);  // pipeline thread
  void erase(const LodKey& k);                         // pipeline thread
  size_t size() const { return count_.load(std::memory_order_relaxed); }
  // Meshes with their encodings and cached deltas (also of replaced versions still held).
  size_t memory_bytes() const {
    return bytes_.load(std::memory_order_relaxed) + delta_bytes_->load(std::memory_order_relaxed);
  }

 private:
  mutable std::mutex mutex_;  // leaf lock
  std::unordered_map<LodKey, MeshVersionPtr, LodKeyHash> meshes_;
  std::atomic<size_t> count_{0}, bytes_{0};
  std::shared_ptr<std::atomic<size_t>> delta_bytes_ = std::make_shared<std::atomic<size_t>>(0);
};

}  // namespace vox::pipeline
