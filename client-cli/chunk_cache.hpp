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

class ChunkCache {
 public:
  // Returns an error message when the payload does not apply or decode (wrong base,
  // corruption); the chunk is then dropped.
  std::optional<std::string> apply(const wire::ChunkMesh& m, proto::ZstdCodec& zstd, proto::CodecScratch& scratch,
                                   mesh::ChunkMesh& decoded);
  void forget(const wire::ChunkUnload& u);
  const std::map<ChunkKey, HeldChunk>& chunks() const { return chunks_; }

 private:
  std::map<ChunkKey, HeldChunk> chunks_;
};

}  // namespace vox::client
