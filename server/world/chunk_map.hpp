// Sparse map of loaded chunks keyed by chunk coordinate. Not thread-safe on its own: the
// world pipeline is its single writer.
#pragma once

#include <cstddef>
#include <unordered_map>

#include "server/world/chunk.hpp"

namespace vox::world {

class ChunkMap {
 public:
  const Chunk* find(ChunkCoord c) const;
  Chunk* find(ChunkCoord c);
  Chunk& insert(ChunkCoord c, Chunk chunk);  // replaces any chunk already there
  bool erase(ChunkCoord c);
  size_t size() const { return chunks_.size(); }
  size_t memory_bytes() const;  // chunk storage, map nodes included approximately; O(1)
  size_t bucket_bytes() const { return chunks_.bucket_count() * sizeof(void*); }
  // A caller that changed a chunk found through find() says whether it was uniform
  // before, so that memory_bytes() stays exact without a scan.
  void note_changed(bool was_uniform, const Chunk& chunk);

  auto begin() const { return chunks_.begin(); }
  auto end() const { return chunks_.end(); }

  // Sample at a world voxel coordinate; air when the chunk is not loaded.
  Sample sample_at(int32_t vx, int32_t vy, int32_t vz) const;

 private:
  std::unordered_map<ChunkCoord, Chunk, ChunkCoordHash> chunks_;
  size_t full_chunks_ = 0;  // chunks that are not uniform (they own sample arrays)
};

}  // namespace vox::world
