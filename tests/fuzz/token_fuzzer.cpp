// libFuzzer target for the player token parser (server/auth/player_token.cpp), as voxeld
// runs it on Hello.token: any text is refused or accepted without a crash, and nothing
// is accepted that a key other than the game's signed. The first input byte picks the
// form: odd, the rest is the token text as sent; even, the rest is the token's bytes
// (base64url-encoded here), so the fuzzer reaches the field parsing behind the text.
#include <sodium.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "server/auth/player_token.hpp"

namespace {

using namespace vox;

const auth::PublicKey& game_key() {
  static const auth::PublicKey key = auth::public_key_of(auth::SecretSeed{7});
  return key;
}

std::string base64url(const uint8_t* data, size_t size) {
  std::string text(sodium_base64_encoded_len(size, sodium_base64_VARIANT_URLSAFE_NO_PADDING), '\0');
  sodium_bin2base64(text.data(), text.size(), data, size, sodium_base64_VARIANT_URLSAFE_NO_PADDING);
  text.resize(text.find('\0'));
  return text;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0 || sodium_init() < 0) return 0;
  const std::string token = data[0] & 1
                                ? std::string(reinterpret_cast<const char*>(data) + 1, size - 1)
                                : base64url(data + 1, size - 1);
  const auth::VerifiedToken v = auth::verify_token(token, game_key(), 1'800'000'000);
  if (v.claims.has_value() != (v.error == auth::TokenError::kNone)) std::abort();
  if (v.claims && (v.claims->player_id.empty() || v.claims->player_id.size() > 64 ||
                   v.claims->display_name.empty() || v.claims->display_name.size() > 32)) {
    std::abort();
  }
  return 0;
}
