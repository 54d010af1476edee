#include "server/net/log_hygiene.hpp"

namespace vox::net {

std::string escape_for_log(std::string_view s, size_t max_bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  const size_t n = std::min(s.size(), max_bytes);
  out.reserve(n + 8);
  for (size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\' && c != '"' && c != '\'') {
      out.push_back(static_cast<char>(c));
    } else {
      out += "\\x";
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 15]);
    }
  }
  if (s.size() > max_bytes) out += "...";
  return out;
}

std::optional<size_t> LogRateLimit::allow(const std::string& kind, Clock::time_point now,
                                          size_t per_interval) {
  Kind& k = kinds_[kind];
  if (k.written == 0 || now - k.window >= interval_) {
    k.window = now;
    k.written = 0;
  }
  if (k.written >= per_interval) {
    ++k.suppressed;
    return std::nullopt;
  }
  ++k.written;
  const size_t suppressed = k.suppressed;
  k.suppressed = 0;
  return suppressed;
}

}  // namespace vox::net
