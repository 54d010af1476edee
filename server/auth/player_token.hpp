// Signed player tokens: the game's backend mints one per player (claims: player id,
// display name, role, expiry, optional edit-budget overrides) and signs it with Ed25519;
// voxeld verifies it offline with the public key. docs/PROTOCOL.md ("Player tokens")
// gives the format byte by byte, with a worked example, so a backend in any language can
// mint them. Pure functions; any thread.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace vox::auth {

enum class Role : uint8_t { kViewer = 0, kPlayer = 1, kAdmin = 2 };
const char* to_string(Role r);
std::optional<Role> parse_role(std::string_view name);  // "viewer", "player", "admin"

struct PlayerClaims {
  std::string player_id;     // 1..64 bytes of UTF-8, no control characters
  std::string display_name;  // 1..32 bytes of UTF-8, no control characters
  Role role = Role::kPlayer;
  int64_t expires_at = 0;   // unix seconds: the first second the token is no longer valid
  uint32_t edit_rate = 0;   // edit budget refill, samples/s; 0: the role's default
  uint32_t edit_burst = 0;  // edit budget capacity, samples; 0: the role's default
  bool operator==(const PlayerClaims&) const = default;
};

using PublicKey = std::array<uint8_t, 32>;
using SecretSeed = std::array<uint8_t, 32>;  // an Ed25519 private key (RFC 8032's 32 bytes)

struct KeyPair {
  PublicKey public_key;
  SecretSeed seed;
};
KeyPair generate_key_pair();
PublicKey public_key_of(const SecretSeed& seed);

// Key files hold one key as unpadded base64url text and a newline. A private key file
// starts with a comment line (kPrivateKeyComment), so that it is never taken for a public
// key: key_from_text refuses it; private_key_from_text skips it and requires it (a public
// key file given as a private key is refused, not turned into tokens no server accepts).
inline constexpr std::string_view kPrivateKeyComment =
    "# voxeld player-token PRIVATE key: keep it on the game's backend, never give it to voxeld\n";
std::string key_to_text(const std::array<uint8_t, 32>& key);
std::optional<std::array<uint8_t, 32>> key_from_text(std::string_view text);  // nullopt: malformed
std::optional<SecretSeed> private_key_from_text(std::string_view text);       // after '#...' lines
// A private key file (voxel-cli keygen's NAME.key); throws std::runtime_error naming the
// path when it cannot be read or holds no private key.
SecretSeed read_private_key_file(const std::string& path);

// Once at start (voxeld with --auth-public-key): throws std::runtime_error if libsodium
// cannot start. Every function here also starts it on first use.
void init_crypto();

enum class TokenError : uint8_t {
  kNone = 0,
  kMissing,       // empty
  kTooLarge,      // over kMaxTokenChars
  kMalformed,     // not base64url, wrong length, or a field out of range
  kUnsupported,   // a version byte this server does not know
  kBadSignature,  // signed with another key, or altered
  kExpired,
};
const char* to_string(TokenError e);

inline constexpr size_t kMaxTokenChars = 512;
inline constexpr uint8_t kTokenVersion = 1;

// Throws std::invalid_argument when a claim is out of range (empty id, name too long...).
std::string mint_token(const PlayerClaims& claims, const SecretSeed& seed);

struct VerifiedToken {
  TokenError error = TokenError::kNone;
  std::string message;                 // for the client's Error and the log, when refused
  std::optional<PlayerClaims> claims;  // when error == kNone
};
VerifiedToken verify_token(std::string_view token, const PublicKey& key, int64_t now_unix);

}  // namespace vox::auth
