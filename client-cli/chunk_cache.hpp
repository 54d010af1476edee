// The chunks a client holds: per chunk the version and its decompressed encoding (the
// base for the next delta). Applies ChunkMesh messages, full or delta.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <tuple>
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

class ChunkCache {
 public:
  // Returns an error message when the payload does not apply or decode (wrong base,
  // corruption); the chunk is then dropped.
  std::optional<std::string> apply(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                   proto::CodecScratch& scratch, mesh::ChunkMesh& decoded);
  // apply() in two steps, for a caller that checks the encoding its own way: expand()
  // decompresses the payload against the held base (on failure the chunk is dropped and
  // the error returned); hold() then keeps the checked encoding, drop() forgets the chunk.
  proto::Result<std::vector<uint8_t>> expand(const wire::ChunkMesh& m, proto::ZstdCodec& zstd);
  void hold(const ChunkKey& key, uint64_t version, std::vector<uint8_t> encoding);
  void drop(const ChunkKey& key) { chunks_.erase(key); }
  void forget(const wire::ChunkUnload& u);
  const std::map<ChunkKey, HeldChunk>& chunks() const { return chunks_; }

 private:
  std::map<ChunkKey, HeldChunk> chunks_;
};

}  // namespace vox::client
