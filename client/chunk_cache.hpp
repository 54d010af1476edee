// The chunks a client holds: per chunk the version and its decompressed encoding (the
// base for the next delta). Applies ChunkMesh messages, full or delta.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "voxel.pb.h"

namespace vox::client {

struct HeldChunk {
  uint64_t version = 0;
  std::vector<uint8_t> encoding;
};

using ChunkKey = std::tuple<int, int, int>;
inline ChunkKey key_of(const wire::ChunkCoord& c) { return {c.x(), c.y(), c.z()}; }
// The chunk holding voxel (x, y, z): floor(v / 32) on each axis (docs/PROTOCOL.md); in
// C++20 >> of a negative int is arithmetic, so it floors.
inline ChunkKey chunk_of_voxel(int x, int y, int z) { return {x >> 5, y >> 5, z >> 5}; }
struct ChunkKeyHash {
  size_t operator()(const ChunkKey& k) const {
    const auto [x, y, z] = k;
    uint64_t h = static_cast<uint32_t>(x) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<uint32_t>(y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= static_cast<uint32_t>(z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return static_cast<size_t>(h);
  }
};
// Held chunks by coordinate; unordered (a player's cache is looked up for every message,
// and an ordered tree's pointer chasing was 13 % of the load tester's CPU).
using HeldChunks = std::unordered_map<ChunkKey, HeldChunk, ChunkKeyHash>;

class ChunkCache {
 public:
  // Returns an error message when the payload does not apply or decode (wrong base,
  // corruption); the chunk is then dropped.
  std::optional<std::string> apply(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                   proto::CodecScratch& scratch, mesh::ChunkMesh& decoded);
  // apply() in two steps, for a caller that checks the encoding its own way: expand()
  // decompresses the payload against the held base into `out` (on failure the chunk is
  // dropped and the error returned); hold() then keeps a copy of the checked encoding
  // (reusing the held one's capacity, so a warm cache allocates nothing per message),
  // drop() forgets the chunk.
  std::optional<std::string> expand(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                    mesh::Buffer<uint8_t>& out);
  void hold(const ChunkKey& key, uint64_t version, std::span<const uint8_t> encoding);
  void drop(const ChunkKey& key) { chunks_.erase(key); }
  void forget(const wire::ChunkUnload& u);
  const HeldChunks& chunks() const { return chunks_; }

 private:
  HeldChunks chunks_;
  mesh::Buffer<uint8_t> scratch_;  // apply()'s expanded payload, reused
};

}  // namespace vox::client
