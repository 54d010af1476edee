#include "loadtest/player_tokens.hpp"

#include <algorithm>

namespace vox::loadtest {

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
