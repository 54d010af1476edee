// --token-key: signed player tokens (server/auth/player_token.hpp) for the simulated
// players, so a load test can run against a voxeld started with --auth-public-key. They
// are minted before the run starts: minting is not in the measured path.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "server/auth/player_token.hpp"

namespace vox::loadtest {

// Player `n`'s claims: id "sim-<n>", name "sim<n>", role player, the role's edit budget.
auth::PlayerClaims sim_player_claims(int n, int64_t expires_at);

// One token per player 0..players-1, in order.
std::vector<std::string> mint_player_tokens(const auth::SecretSeed& key, int players,
                                            int64_t expires_at);

}  // namespace vox::loadtest
