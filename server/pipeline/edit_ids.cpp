#include "server/pipeline/edit_ids.hpp"

#include <sodium.h>

#include <stdexcept>
#include <vector>

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

uint64_t EditIds::of_player(const Key& key, std::string_view player, uint64_t client_id) {
  if (client_id == 0) return 0;
  // The player id, a separator no id holds, then the client's id.
  std::vector<uint8_t> message(player.begin(), player.end());
  message.push_back(0);
  for (int i = 0; i < 8; ++i) message.push_back(static_cast<uint8_t>(client_id >> (8 * i)));
  std::array<uint8_t, crypto_shorthash_BYTES> out{};
  crypto_shorthash(out.data(), message.data(), message.size(), key.data());
  uint64_t h = 0;
  for (int i = 0; i < 8; ++i) h |= uint64_t{out[i]} << (8 * i);
  return h == 0 ? 1 : h;
}

EditIds::Key EditIds::random_key() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot start");
  Key key;
  randombytes_buf(key.data(), key.size());
  return key;
}

EditIds::Key EditIds::key_from_secret(std::string_view secret) {
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot start");
  Key key;
  static constexpr std::string_view kContext = "voxeld edit ids 1";
  crypto_generichash_state state;
  crypto_generichash_init(&state, nullptr, 0, key.size());
  crypto_generichash_update(&state, reinterpret_cast<const uint8_t*>(kContext.data()),
                            kContext.size());
  crypto_generichash_update(&state, reinterpret_cast<const uint8_t*>(secret.data()), secret.size());
  crypto_generichash_final(&state, key.data(), key.size());
  return key;
}

}  // namespace vox::pipeline
