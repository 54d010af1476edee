#include "server/net/proxy_header.hpp"

#include <algorithm>

namespace vox::net {
namespace {

constexpr std::array<uint8_t, 12> kSignature = {0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D,
                                                0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};

}  // namespace

std::optional<size_t> proxy_v2_rest(std::span<const uint8_t, kProxyHeadBytes> head,
                                    std::string& why) {
  if (!std::equal(kSignature.begin(), kSignature.end(), head.begin())) {
    why = "no PROXY protocol v2 signature (the proxy must send-proxy-v2)";
    return std::nullopt;
  }
  if ((head[12] >> 4) != 2 || (head[12] & 0x0F) > 1) {
    why = "a PROXY header of another version or command";
    return std::nullopt;
  }
  const size_t rest = (size_t{head[14]} << 8) | head[15];
  if (rest > kMaxProxyRestBytes) {
    why = "a PROXY header of " + std::to_string(rest) + " bytes (at most " +
          std::to_string(kMaxProxyRestBytes) + ")";
    return std::nullopt;
  }
  return rest;
}

std::optional<ProxyClient> parse_proxy_v2(std::span<const uint8_t, kProxyHeadBytes> head,
                                          std::span<const uint8_t> rest, std::string& why) {
  const std::optional<size_t> length = proxy_v2_rest(head, why);
  if (!length) return std::nullopt;
  if (rest.size() != *length) {
    why = "a PROXY header shorter than it says";
    return std::nullopt;
  }
  ProxyClient out;
  if ((head[12] & 0x0F) == 0) return out;  // LOCAL: the proxy's own connection
  const uint8_t family = head[13] >> 4, transport = head[13] & 0x0F;
  if (family == 0) return out;  // UNSPEC: no address given
  if (transport != 1 || (family != 1 && family != 2)) {
    why = "a PROXY header for something other than TCP over IPv4 or IPv6";
    return std::nullopt;
  }
  const size_t need = family == 1 ? 12 : 36;
  if (rest.size() < need) {
    why = "a PROXY header too short for its addresses";
    return std::nullopt;
  }
  if (family == 1) {
    boost::asio::ip::address_v4::bytes_type b;
    std::copy_n(rest.begin(), 4, b.begin());
    out.address = boost::asio::ip::address_v4(b);
  } else {
    boost::asio::ip::address_v6::bytes_type b;
    std::copy_n(rest.begin(), 16, b.begin());
    out.address = boost::asio::ip::address_v6(b);
  }
  return out;
}

}  // namespace vox::net
