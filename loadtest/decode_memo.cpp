#include "loadtest/decode_memo.hpp"

#include <algorithm>

namespace vox::loadtest {

DecodeMemo::Shard& DecodeMemo::shard_of(const client::ChunkKey& key) const {
  return shards_[client::ChunkKeyHash{}(key) % kShards];
}

bool DecodeMemo::known_good(const client::ChunkKey& key, uint64_t version,
                            std::span<const uint8_t> encoding) const {
  std::shared_ptr<const std::vector<uint8_t>> good;
  {
    Shard& s = shard_of(key);
    std::lock_guard lock(s.mutex);
    auto it = s.entries.find(key);
    if (it == s.entries.end() || it->second.version != version) return false;
    good = it->second.encoding;
  }
  return std::equal(encoding.begin(), encoding.end(), good->begin(), good->end());
}

void DecodeMemo::remember(const client::ChunkKey& key, uint64_t version,
                          std::span<const uint8_t> encoding) {
  auto copy = std::make_shared<const std::vector<uint8_t>>(encoding.begin(), encoding.end());
  Shard& s = shard_of(key);
  std::lock_guard lock(s.mutex);
  Entry& e = s.entries[key];
  if (e.encoding && e.version >= version) return;
  e.version = version;
  e.encoding = std::move(copy);
}

}  // namespace vox::loadtest
