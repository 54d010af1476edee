// Player tokens (server/auth): what a backend mints verifies, and every way a token can be
// wrong is refused with its own error, without a crash on any byte string.
#include "server/auth/player_token.hpp"

#include <gtest/gtest.h>

#include <string>

namespace vox::auth {
namespace {

constexpr int64_t kNow = 1'800'000'000;

// RFC 8032's first test key: the worked example in docs/PROTOCOL.md uses it.
SecretSeed rfc8032_seed() { return *key_from_text("nWGxne_9WmC6hEr0kuwsxERJxWl7MmkZcDusAxyuf2A"); }

PlayerClaims alice() {
  return {.player_id = "alice-0001",
          .display_name = "Alice",
          .role = Role::kPlayer,
          .expires_at = kNow + 3600};
}

TEST(PlayerToken, AMintedTokenVerifiesWithItsPublicKey) {
  const KeyPair k = generate_key_pair();
  PlayerClaims c = alice();
  c.role = Role::kAdmin;
  c.edit_rate = 123456;
  c.edit_burst = 7;
  c.display_name = "Zoë ✓";
  const VerifiedToken v = verify_token(mint_token(c, k.seed), k.public_key, kNow);
  ASSERT_EQ(v.error, TokenError::kNone) << v.message;
  EXPECT_EQ(*v.claims, c);
}

// Pins the format: the worked example in docs/PROTOCOL.md is this token.
TEST(PlayerToken, TheWorkedExampleOfTheProtocolPage) {
  const SecretSeed seed = rfc8032_seed();
  EXPECT_EQ(key_to_text(public_key_of(seed)), "11qYAYKxCrfVS_7TyWQHOg7hcvPapiMlrwIaaPcHURo\n");
  PlayerClaims c = alice();
  c.expires_at = 1'800'000'000;
  const std::string token = mint_token(c, seed);
  // Checked against another Ed25519 implementation (Python's `cryptography`).
  EXPECT_EQ(
      token,
      "AQDSSWsAAAAAAQAAAAAAAAAACmFsaWNlLTAwMDEFQWxpY2VAEzJA_3WF-XoxiWwuS__tDcrzoh1e58XLE6zXjyi0"
      "ZnpI0RkitvNnsY0tp7Ha9Ls9s6R5XS909a2HMuKbW7oN");
}

TEST(PlayerToken, AnExpiredTokenIsRefused) {
  const KeyPair k = generate_key_pair();
  const std::string t = mint_token(alice(), k.seed);
  EXPECT_EQ(verify_token(t, k.public_key, kNow + 3599).error, TokenError::kNone);
  EXPECT_EQ(verify_token(t, k.public_key, kNow + 3600).error, TokenError::kExpired);
}

TEST(PlayerToken, AnotherKeysTokenIsRefused) {
  const KeyPair k = generate_key_pair(), other = generate_key_pair();
  EXPECT_EQ(verify_token(mint_token(alice(), other.seed), k.public_key, kNow).error,
            TokenError::kBadSignature);
}

// Every byte changed in turn: never accepted (the version byte says unsupported, a length
// byte malformed, anything else the signature).
TEST(PlayerToken, EveryAlteredByteIsRefused) {
  const KeyPair k = generate_key_pair();
  const std::string t = mint_token(alice(), k.seed);
  for (size_t i = 0; i < t.size(); ++i) {
    for (char replacement : {'A', 'B', '_', '-', 'z'}) {
      if (t[i] == replacement) continue;
      std::string altered = t;
      altered[i] = replacement;
      const VerifiedToken v = verify_token(altered, k.public_key, kNow);
      EXPECT_NE(v.error, TokenError::kNone) << "character " << i << " -> " << replacement;
      EXPECT_FALSE(v.claims.has_value());
    }
  }
}

TEST(PlayerToken, TruncatedAndOversizedTokensAreRefused) {
  const KeyPair k = generate_key_pair();
  const std::string t = mint_token(alice(), k.seed);
  EXPECT_EQ(verify_token("", k.public_key, kNow).error, TokenError::kMissing);
  for (size_t n = 1; n < t.size(); ++n)
    EXPECT_NE(verify_token(t.substr(0, n), k.public_key, kNow).error, TokenError::kNone) << n;
  EXPECT_EQ(verify_token(t + "AAAA", k.public_key, kNow).error, TokenError::kMalformed);
  EXPECT_EQ(verify_token(std::string(kMaxTokenChars + 1, 'A'), k.public_key, kNow).error,
            TokenError::kTooLarge);
  EXPECT_EQ(verify_token("not base64!", k.public_key, kNow).error, TokenError::kMalformed);
  EXPECT_EQ(verify_token(t + "=", k.public_key, kNow).error, TokenError::kMalformed);
}

TEST(PlayerToken, AnotherVersionByteIsUnsupported) {
  const KeyPair k = generate_key_pair();
  std::string t = mint_token(alice(), k.seed);
  t[0] = 'A';
  t[1] = 'g';  // the first byte becomes 2
  EXPECT_EQ(verify_token(t, k.public_key, kNow).error, TokenError::kUnsupported);
}

TEST(PlayerToken, ClaimsOutOfRangeAreNotMinted) {
  const SecretSeed seed = rfc8032_seed();
  PlayerClaims c = alice();
  c.player_id = "";
  EXPECT_THROW(mint_token(c, seed), std::invalid_argument);
  c.player_id = std::string(65, 'a');
  EXPECT_THROW(mint_token(c, seed), std::invalid_argument);
  c = alice();
  c.display_name = std::string(33, 'a');
  EXPECT_THROW(mint_token(c, seed), std::invalid_argument);
  c.display_name = "bell\x07";
  EXPECT_THROW(mint_token(c, seed), std::invalid_argument);
  c.display_name = "\xc0\xaf";  // overlong '/'
  EXPECT_THROW(mint_token(c, seed), std::invalid_argument);
}

TEST(PlayerToken, KeysRoundTripAsText) {
  const KeyPair k = generate_key_pair();
  EXPECT_EQ(key_from_text(key_to_text(k.public_key)), k.public_key);
  EXPECT_EQ(public_key_of(*key_from_text(key_to_text(k.seed))), k.public_key);
  EXPECT_FALSE(key_from_text("AAAA").has_value());
  EXPECT_FALSE(key_from_text("").has_value());
  EXPECT_FALSE(key_from_text(std::string(43, '!')).has_value());
}

// A private key file given as --auth-public-key would put the backend's key on the game
// server (and refuse every token): its comment line makes it no public key file.
TEST(PlayerToken, APrivateKeyFileIsNoPublicKeyFile) {
  const KeyPair k = generate_key_pair();
  const std::string file = std::string(kPrivateKeyComment) + key_to_text(k.seed);
  EXPECT_FALSE(key_from_text(file).has_value());
  EXPECT_EQ(private_key_from_text(file), k.seed);
  EXPECT_FALSE(private_key_from_text(key_to_text(k.seed)).has_value())
      << "a public key file (no comment line) is no private key file";
}

TEST(PlayerToken, RolesHaveNames) {
  for (Role r : {Role::kViewer, Role::kPlayer, Role::kAdmin})
    EXPECT_EQ(parse_role(to_string(r)), r);
  EXPECT_FALSE(parse_role("root").has_value());
}

}  // namespace
}  // namespace vox::auth
