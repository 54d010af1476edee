#include "loadtest/decode_memo.hpp"

#include <algorithm>

namespace vox::loadtest {

size_t DecodeMemo::KeyHash::operator()(const client::ChunkKey& k) const {
  const auto [x, y, z] = k;
  uint64_t h = static_cast<uint32_t>(x) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<uint32_t>(y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
  h ^= static_cast<uint32_t>(z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
  return static_cast<size_t>(h);
}

DecodeMemo::Shard& DecodeMemo::shard_of(const client::ChunkKey& key) const {
  return shards_[KeyHash{}(key) % kShards];
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
