#include "loadtest/decode_memo.hpp"

#include <algorithm>

namespace vox::loadtest {
namespace {

bool same(const std::vector<uint8_t>* a, std::span<const uint8_t> b) {
  return a && std::equal(b.begin(), b.end(), a->begin(), a->end());
}

}  // namespace

DecodeMemo::Shard& DecodeMemo::shard_of(const MemoKey& key) const {
  return shards_[KeyHash{}(key) % kShards];
}

bool DecodeMemo::known_good(const MemoKey& key, std::span<const uint8_t> encoding) const {
  std::array<Encoding, kKept> recent;
  {
    Shard& s = shard_of(key);
    std::lock_guard lock(s.mutex);
    auto it = s.entries.find(key);
    if (it == s.entries.end()) return false;
    recent = it->second.recent;
  }
  // Compared outside the lock: the encodings are immutable and shared.
  return std::any_of(recent.begin(), recent.end(),
                     [&](const Encoding& e) { return same(e.get(), encoding); });
}

void DecodeMemo::remember(const MemoKey& key, std::span<const uint8_t> encoding) {
  auto copy = std::make_shared<const std::vector<uint8_t>>(encoding.begin(), encoding.end());
  Shard& s = shard_of(key);
  std::lock_guard lock(s.mutex);
  auto& recent = s.entries[key].recent;
  auto it = std::find_if(recent.begin(), recent.end(),
                         [&](const Encoding& e) { return same(e.get(), encoding); });
  if (it == recent.end()) it = recent.end() - 1;  // a new one: the oldest goes
  std::rotate(recent.begin(), it, it + 1);        // to the front
  if (!same(recent.front().get(), encoding)) recent.front() = std::move(copy);
  if (key.level == 0)  // a long soak edits thousands of chunks: keep the newest few only
    std::fill(recent.begin() + kKeptLevel0, recent.end(), nullptr);
}

}  // namespace vox::loadtest
