#include "server/auth/player_token.hpp"

#include <sodium.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <vector>

namespace vox::auth {

namespace {

// Signed with the body, never sent: a signature made for anything else never verifies.
constexpr std::string_view kContext = "voxeld-token-v1";
constexpr size_t kHeaderBytes = 18;  // version, expires_at, role, edit_rate, edit_burst
constexpr size_t kSignatureBytes = crypto_sign_BYTES;
constexpr size_t kMaxIdBytes = 64, kMaxNameBytes = 32;

// Well-formed UTF-8 (no overlong forms, surrogates or code points past U+10FFFF), no
// control characters: a claim is printed in logs and tools.
bool printable_utf8(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const auto b = static_cast<uint8_t>(s[i]);
    if (b < 0x80) {
      if (b < 0x20 || b == 0x7f) return false;
      ++i;
      continue;
    }
    const size_t n = b >= 0xf0 ? 4 : b >= 0xe0 ? 3 : b >= 0xc0 ? 2 : 0;
    if (n == 0 || b > 0xf4 || i + n > s.size()) return false;
    uint32_t cp = b & (0x7f >> n);
    for (size_t k = 1; k < n; ++k) {
      const auto c = static_cast<uint8_t>(s[i + k]);
      if ((c & 0xc0) != 0x80) return false;
      cp = (cp << 6) | (c & 0x3f);
    }
    static constexpr uint32_t kMin[] = {0, 0, 0x80, 0x800, 0x10000};
    if (cp < kMin[n] || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return false;
    if (cp >= 0x80 && cp < 0xa0) return false;  // C1 controls
    i += n;
  }
  return true;
}

bool valid_text(std::string_view s, size_t max_bytes) {
  return !s.empty() && s.size() <= max_bytes && printable_utf8(s);
}

void put_le(std::vector<uint8_t>& out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

uint64_t get_le(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

std::vector<uint8_t> signed_message(const uint8_t* body, size_t size) {
  std::vector<uint8_t> m;
  m.reserve(kContext.size() + size);
  for (char ch : kContext) m.push_back(static_cast<uint8_t>(ch));
  m.insert(m.end(), body, body + size);
  return m;
}

}  // namespace

void init_crypto() {
  static const bool ready = sodium_init() >= 0;
  if (!ready) throw std::runtime_error("libsodium could not be initialised");
}

namespace {

std::string to_base64url(const uint8_t* bytes, size_t size) {
  constexpr int kVariant = sodium_base64_VARIANT_URLSAFE_NO_PADDING;
  std::string text(sodium_base64_encoded_len(size, kVariant), '\0');
  sodium_bin2base64(text.data(), text.size(), bytes, size, kVariant);
  text.resize(std::strlen(text.c_str()));
  return text;
}

std::optional<std::vector<uint8_t>> from_base64url(std::string_view text) {
  std::vector<uint8_t> bytes(text.size() * 3 / 4 + 3);
  size_t size = 0;
  const char* end = nullptr;
  if (sodium_base642bin(bytes.data(), bytes.size(), text.data(), text.size(), nullptr, &size, &end,
                        sodium_base64_VARIANT_URLSAFE_NO_PADDING) != 0 ||
      end != text.data() + text.size()) {
    return std::nullopt;
  }
  bytes.resize(size);
  return bytes;
}

VerifiedToken refused(TokenError e, std::string message) {
  return {e, std::move(message), std::nullopt};
}

}  // namespace

const char* to_string(Role r) {
  switch (r) {
    case Role::kViewer:
      return "viewer";
    case Role::kPlayer:
      return "player";
    case Role::kAdmin:
      return "admin";
  }
  return "unknown";
}

std::optional<Role> parse_role(std::string_view name) {
  for (Role r : {Role::kViewer, Role::kPlayer, Role::kAdmin})
    if (name == to_string(r)) return r;
  return std::nullopt;
}

const char* to_string(TokenError e) {
  switch (e) {
    case TokenError::kNone:
      return "valid";
    case TokenError::kMissing:
      return "missing";
    case TokenError::kTooLarge:
      return "too large";
    case TokenError::kMalformed:
      return "malformed";
    case TokenError::kUnsupported:
      return "unsupported version";
    case TokenError::kBadSignature:
      return "bad signature";
    case TokenError::kExpired:
      return "expired";
  }
  return "unknown";
}

KeyPair generate_key_pair() {
  init_crypto();
  KeyPair k;
  randombytes_buf(k.seed.data(), k.seed.size());
  k.public_key = public_key_of(k.seed);
  return k;
}

PublicKey public_key_of(const SecretSeed& seed) {
  init_crypto();
  PublicKey pk;
  std::array<uint8_t, crypto_sign_SECRETKEYBYTES> sk;
  crypto_sign_seed_keypair(pk.data(), sk.data(), seed.data());
  sodium_memzero(sk.data(), sk.size());
  return pk;
}

std::string key_to_text(const std::array<uint8_t, 32>& key) {
  init_crypto();
  return to_base64url(key.data(), key.size()) + "\n";
}

std::optional<std::array<uint8_t, 32>> key_from_text(std::string_view text) {
  init_crypto();
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' '))
    text.remove_suffix(1);
  const auto bytes = from_base64url(text);
  if (!bytes || bytes->size() != 32) return std::nullopt;
  std::array<uint8_t, 32> key;
  std::memcpy(key.data(), bytes->data(), key.size());
  return key;
}

std::optional<SecretSeed> private_key_from_text(std::string_view text) {
  if (text.empty() || text.front() != '#') return std::nullopt;  // a public key file
  while (!text.empty() && text.front() == '#') {
    const size_t end = text.find('\n');
    text.remove_prefix(end == std::string_view::npos ? text.size() : end + 1);
  }
  return key_from_text(text);
}

SecretSeed read_private_key_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto key = private_key_from_text(text);
  if (!key)
    throw std::runtime_error(path +
                             ": not a private key file (voxel-cli keygen writes NAME.key; NAME.pub "
                             "is the public key)");
  return *key;
}

std::string mint_token(const PlayerClaims& c, const SecretSeed& seed) {
  init_crypto();
  if (!valid_text(c.player_id, kMaxIdBytes))
    throw std::invalid_argument("the player id must be 1..64 bytes of printable UTF-8");
  if (!valid_text(c.display_name, kMaxNameBytes))
    throw std::invalid_argument("the display name must be 1..32 bytes of printable UTF-8");
  std::vector<uint8_t> body;
  body.push_back(kTokenVersion);
  put_le(body, static_cast<uint64_t>(c.expires_at), 8);
  body.push_back(static_cast<uint8_t>(c.role));
  put_le(body, c.edit_rate, 4);
  put_le(body, c.edit_burst, 4);
  body.push_back(static_cast<uint8_t>(c.player_id.size()));
  body.insert(body.end(), c.player_id.begin(), c.player_id.end());
  body.push_back(static_cast<uint8_t>(c.display_name.size()));
  body.insert(body.end(), c.display_name.begin(), c.display_name.end());
  std::array<uint8_t, crypto_sign_PUBLICKEYBYTES> pk;
  std::array<uint8_t, crypto_sign_SECRETKEYBYTES> sk;
  crypto_sign_seed_keypair(pk.data(), sk.data(), seed.data());
  const std::vector<uint8_t> message = signed_message(body.data(), body.size());
  std::array<uint8_t, kSignatureBytes> signature;
  crypto_sign_detached(signature.data(), nullptr, message.data(), message.size(), sk.data());
  sodium_memzero(sk.data(), sk.size());
  body.insert(body.end(), signature.begin(), signature.end());
  return to_base64url(body.data(), body.size());
}

VerifiedToken verify_token(std::string_view token, const PublicKey& key, int64_t now_unix) {
  init_crypto();
  if (token.empty()) return refused(TokenError::kMissing, "a token is required");
  if (token.size() > kMaxTokenChars)
    return refused(TokenError::kTooLarge, "the token is over 512 characters");
  const auto bytes = from_base64url(token);
  if (!bytes) return refused(TokenError::kMalformed, "the token is not unpadded base64url");
  const std::vector<uint8_t>& b = *bytes;
  if (b.empty()) return refused(TokenError::kMalformed, "the token is empty");
  if (b[0] != kTokenVersion)
    return refused(TokenError::kUnsupported,
                   "unsupported version: the token's version byte is not 1");
  // Lengths first: the signature covers every byte before it, wherever it ends.
  size_t at = kHeaderBytes;
  if (b.size() < at + 1) return refused(TokenError::kMalformed, "the token is truncated");
  const size_t id_len = b[at++];
  if (b.size() < at + id_len + 1) return refused(TokenError::kMalformed, "the token is truncated");
  const size_t name_at = at + id_len + 1;
  const size_t name_len = b[at + id_len];
  if (b.size() != name_at + name_len + kSignatureBytes) {
    return refused(TokenError::kMalformed, b.size() < name_at + name_len + kSignatureBytes
                                               ? "the token is truncated"
                                               : "the token has bytes after its signature");
  }
  const size_t body_size = b.size() - kSignatureBytes;
  const std::vector<uint8_t> message = signed_message(b.data(), body_size);
  if (crypto_sign_verify_detached(b.data() + body_size, message.data(), message.size(),
                                  key.data()) != 0) {
    return refused(TokenError::kBadSignature, "the token's signature does not verify");
  }
  PlayerClaims c;
  c.expires_at = static_cast<int64_t>(get_le(b.data() + 1, 8));
  const uint8_t role = b[9];
  c.edit_rate = static_cast<uint32_t>(get_le(b.data() + 10, 4));
  c.edit_burst = static_cast<uint32_t>(get_le(b.data() + 14, 4));
  c.player_id.assign(reinterpret_cast<const char*>(b.data() + kHeaderBytes + 1), id_len);
  c.display_name.assign(reinterpret_cast<const char*>(b.data() + name_at), name_len);
  if (role > static_cast<uint8_t>(Role::kAdmin))
    return refused(TokenError::kMalformed, "the token's role is not 0, 1 or 2");
  c.role = static_cast<Role>(role);
  if (!valid_text(c.player_id, kMaxIdBytes) || !valid_text(c.display_name, kMaxNameBytes))
    return refused(TokenError::kMalformed, "the token's player id or name is not valid text");
  if (now_unix >= c.expires_at) return refused(TokenError::kExpired, "the token has expired");
  return {TokenError::kNone, {}, std::move(c)};
}

}  // namespace vox::auth
