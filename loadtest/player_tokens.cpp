#include "loadtest/player_tokens.hpp"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace vox::loadtest {

auth::SecretSeed read_private_key_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto key = auth::private_key_from_text(text);
  if (!key)
    throw std::runtime_error(path + ": not a private key (voxel-cli keygen writes NAME.key)");
  return *key;
}

auth::PlayerClaims sim_player_claims(int n, int64_t expires_at) {
  return {.player_id = "sim-" + std::to_string(n),
          .display_name = "sim" + std::to_string(n),
          .role = auth::Role::kPlayer,
          .expires_at = expires_at};
}

std::vector<std::string> mint_player_tokens(const auth::SecretSeed& key, int players,
                                            int64_t expires_at) {
  std::vector<std::string> tokens;
  tokens.reserve(static_cast<size_t>(std::max(0, players)));
  for (int n = 0; n < players; ++n)
    tokens.push_back(auth::mint_token(sim_player_claims(n, expires_at), key));
  return tokens;
}

}  // namespace vox::loadtest
