// Encodings the load test has already decoded successfully, shared by all simulated
// players. Many players receive the same chunk mesh (a full mesh or a delta they each
// expand against their own base); decoding is a pure function of the expanded bytes, so
// a player whose bytes equal a remembered encoding byte for byte knows the outcome without
// decoding again. Without this, the load tester (hundreds of clients in one process)
// spends most of its CPU decoding the same meshes and becomes the bottleneck of the test
// instead of the server. `--decode-all` turns it off.
//
// Kept per (level, chunk): the few most recently decoded distinct encodings. Not the
// version: a coarse chunk's wire versions are the session's own (docs/PROTOCOL.md 4.10),
// and players whose layouts differ hold different seams variants of one chunk at once.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <unordered_map>
#include <vector>

#include "client/chunk_cache.hpp"

namespace vox::loadtest {

struct MemoKey {
  uint32_t level = 0;
  client::ChunkKey chunk;
  friend bool operator==(const MemoKey&, const MemoKey&) = default;
};

class DecodeMemo {
 public:
  // Encodings remembered per (level, chunk): a coarse chunk's seams variants, a level-0
  // chunk's newest versions (players receive them in order, a few apart at most).
  static constexpr size_t kKept = 8;
  static constexpr size_t kKeptLevel0 = 2;

  // True when `encoding` is byte for byte a remembered good encoding of `key`. Any thread.
  bool known_good(const MemoKey& key, std::span<const uint8_t> encoding) const;
  // Remembers a successfully decoded encoding (the oldest of the key's goes). Any thread.
  void remember(const MemoKey& key, std::span<const uint8_t> encoding);

 private:
  using Encoding = std::shared_ptr<const std::vector<uint8_t>>;
  struct Entry {
    std::array<Encoding, kKept> recent;  // newest first
  };
  struct KeyHash {
    size_t operator()(const MemoKey& k) const {
      return client::ChunkKeyHash{}(k.chunk) ^ (size_t{k.level} * 0x9E3779B97F4A7C15ull);
    }
  };
  struct Shard {
    mutable std::mutex mutex;
    std::unordered_map<MemoKey, Entry, KeyHash> entries;
  };
  static constexpr size_t kShards = 16;
  Shard& shard_of(const MemoKey& key) const;
  mutable std::array<Shard, kShards> shards_;
};

}  // namespace vox::loadtest
