#include "world/chunk_map.hpp"

namespace vox::world {

const Chunk* ChunkMap::find(ChunkCoord c) const {
  auto it = chunks_.find(c);
  return it == chunks_.end() ? nullptr : &it->second;
}

Chunk* ChunkMap::find(ChunkCoord c) {
  auto it = chunks_.find(c);
  return it == chunks_.end() ? nullptr : &it->second;
}

Chunk& ChunkMap::insert(ChunkCoord c, Chunk chunk) {
  return chunks_.insert_or_assign(c, std::move(chunk)).first->second;
}

bool ChunkMap::erase(ChunkCoord c) { return chunks_.erase(c) > 0; }

size_t ChunkMap::memory_bytes() const {
  // Node: key + chunk + next pointer + cached hash; plus one bucket pointer per bucket.
  size_t bytes = chunks_.bucket_count() * sizeof(void*);
  for (const auto& [coord, chunk] : chunks_) {
    bytes += sizeof(coord) + 2 * sizeof(void*) + chunk.memory_bytes();
  }
  return bytes;
}

Sample ChunkMap::sample_at(int32_t vx, int32_t vy, int32_t vz) const {
  const Chunk* chunk = find(chunk_of_voxel(vx, vy, vz));
  if (chunk == nullptr) return {};
  return chunk->at(floor_mod(vx, kChunkSize), floor_mod(vy, kChunkSize), floor_mod(vz, kChunkSize));
}

}  // namespace vox::world
