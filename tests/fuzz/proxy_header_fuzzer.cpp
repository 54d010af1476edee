// libFuzzer target for the PROXY protocol v2 header (server/net/proxy_header.cpp), as voxeld
// reads it first on a connection from a trusted proxy: the 16-byte head, then as many
// bytes as it says (at most the bound). Any bytes are refused or give an address, without
// a crash or a read past them.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "server/net/proxy_header.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace vox::net;
  if (size < kProxyHeadBytes) return 0;
  const std::span<const uint8_t, kProxyHeadBytes> head(data, kProxyHeadBytes);
  std::string why;
  const auto rest = proxy_v2_rest(head, why);
  if (!rest || *rest > kMaxProxyRestBytes) return 0;
  const size_t have = std::min(size - kProxyHeadBytes, *rest);
  const auto client = parse_proxy_v2(head, std::span(data + kProxyHeadBytes, have), why);
  if (client && client->address) (void)client->address->to_string();
  return 0;
}
