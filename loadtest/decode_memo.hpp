// Encodings the load test has already decoded successfully, shared by all simulated
// players. Many players receive the same chunk version (a full mesh or a delta they each
// expand against their own base); decoding is a pure function of the expanded bytes, so
// a player whose bytes equal a remembered encoding byte for byte knows the outcome without
// decoding again. Without this, the load tester (500 clients in one process) spends most
// of its CPU decoding the same meshes and becomes the bottleneck of the test instead of
// the server. `--decode-all` turns it off.
#pragma once

#include <array>
#include <memory>
#include <mutex>
#include <span>
#include <unordered_map>
#include <vector>

#include "client/chunk_cache.hpp"

namespace vox::loadtest {

class DecodeMemo {
 public:
  // True when `encoding` is byte for byte the remembered good encoding of key@version.
  bool known_good(const client::ChunkKey& key, uint64_t version,
                  std::span<const uint8_t> encoding) const;
  // Remembers a successfully decoded encoding (the newest version per chunk is kept).
  void remember(const client::ChunkKey& key, uint64_t version, std::span<const uint8_t> encoding);

 private:
  struct Entry {
    uint64_t version = 0;
    std::shared_ptr<const std::vector<uint8_t>> encoding;
  };
  struct Shard {
    mutable std::mutex mutex;
    std::unordered_map<client::ChunkKey, Entry, client::ChunkKeyHash> entries;
  };
  static constexpr size_t kShards = 16;
  Shard& shard_of(const client::ChunkKey& key) const;
  mutable std::array<Shard, kShards> shards_;
};

}  // namespace vox::loadtest
