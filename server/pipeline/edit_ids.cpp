#include "server/pipeline/edit_ids.hpp"

namespace vox::pipeline {

void EditIds::note(uint64_t id) {
  if (id == 0) return;
  const uint64_t now = ++notes_;
  when_[id] = now;
  order_.emplace_back(id, now);
  // Forgotten ids leave entries behind: the queue is bounded too.
  while (order_.size() > capacity_ || (order_.size() > 2 * when_.size() + 64)) {
    const auto [old, at] = order_.front();
    order_.pop_front();
    if (const auto it = when_.find(old); it != when_.end() && it->second == at)
      when_.erase(it);  // noted again since: the later note stays
  }
}

void EditIds::forget(uint64_t id) { when_.erase(id); }

uint64_t EditIds::of_player(std::string_view player, uint64_t client_id) {
  if (client_id == 0) return 0;
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a over the player id, then the client's id
  for (const char ch : player) h = (h ^ static_cast<uint8_t>(ch)) * 0x100000001b3ull;
  for (int i = 0; i < 8; ++i) h = (h ^ ((client_id >> (8 * i)) & 0xff)) * 0x100000001b3ull;
  h ^= h >> 33;  // a final mix (splitmix64's)
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  return h == 0 ? 1 : h;
}

}  // namespace vox::pipeline
