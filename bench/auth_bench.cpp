// Player tokens: what verifying one costs voxeld per Hello (one core), and minting one
// (the game backend's side), with a typical token (16-byte id, 8-byte name).
#include <benchmark/benchmark.h>

#include "server/auth/player_token.hpp"

namespace {

using namespace vox;

constexpr int64_t kNow = 1'800'000'000;

auth::PlayerClaims claims() {
  return {.player_id = "player-0000012345",
          .display_name = "Explorer",
          .role = auth::Role::kPlayer,
          .expires_at = kNow + 3600};
}

void BM_VerifyToken(benchmark::State& state) {
  const auth::KeyPair k = auth::generate_key_pair();
  const std::string token = auth::mint_token(claims(), k.seed);
  for (auto _ : state) {
    auth::VerifiedToken v = auth::verify_token(token, k.public_key, kNow);
    benchmark::DoNotOptimize(v);
    if (!v.claims) state.SkipWithError("the token did not verify");
  }
}
BENCHMARK(BM_VerifyToken)->Unit(benchmark::kMicrosecond);

// A forged token costs the server as much as a real one: the signature is checked last.
void BM_VerifyForgedToken(benchmark::State& state) {
  const auth::KeyPair k = auth::generate_key_pair(), other = auth::generate_key_pair();
  const std::string token = auth::mint_token(claims(), other.seed);
  for (auto _ : state) benchmark::DoNotOptimize(auth::verify_token(token, k.public_key, kNow));
}
BENCHMARK(BM_VerifyForgedToken)->Unit(benchmark::kMicrosecond);

void BM_MintToken(benchmark::State& state) {
  const auth::KeyPair k = auth::generate_key_pair();
  for (auto _ : state) benchmark::DoNotOptimize(auth::mint_token(claims(), k.seed));
}
BENCHMARK(BM_MintToken)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
