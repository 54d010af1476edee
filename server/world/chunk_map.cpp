#include "server/world/chunk_map.hpp"

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
  if (const Chunk* old = find(c); old && !old->is_uniform()) --full_chunks_;
  if (!chunk.is_uniform()) ++full_chunks_;
  return chunks_.insert_or_assign(c, std::move(chunk)).first->second;
}

bool ChunkMap::erase(ChunkCoord c) {
  auto it = chunks_.find(c);
  if (it == chunks_.end()) return false;
  if (!it->second.is_uniform()) --full_chunks_;
  chunks_.erase(it);
  return true;
}

void ChunkMap::note_changed(bool was_uniform, const Chunk& chunk) {
  if (was_uniform && !chunk.is_uniform()) ++full_chunks_;
  if (!was_uniform && chunk.is_uniform()) --full_chunks_;
}

size_t ChunkMap::memory_bytes() const {
  // Node: key + chunk + next pointer + cached hash; plus one bucket pointer per bucket.
  const Chunk uniform;
  const size_t node = sizeof(ChunkCoord) + 2 * sizeof(void*) + uniform.memory_bytes();
  const size_t samples = kChunkVolume * (sizeof(Density) + sizeof(Material));
  return bucket_bytes() + chunks_.size() * node + full_chunks_ * samples;
}

Sample ChunkMap::sample_at(int32_t vx, int32_t vy, int32_t vz) const {
  const Chunk* chunk = find(chunk_of_voxel(vx, vy, vz));
  if (chunk == nullptr) return {};
  return chunk->at(floor_mod(vx, kChunkSize), floor_mod(vy, kChunkSize), floor_mod(vz, kChunkSize));
}

}  // namespace vox::world
