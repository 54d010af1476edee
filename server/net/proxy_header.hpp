// The PROXY protocol, version 2 (HAProxy's `send-proxy-v2`): the binary header a trusted
// proxy sends first on each connection it passes on, naming the client's address
// (docs/CLUSTER.md, "Clients"). Only what voxeld needs: the command and the source
// address. Pure functions: any thread; every byte is checked (the header comes before any
// of voxeld's own framing).
//
//   12 bytes  signature 0D 0A 0D 0A 00 0D 0A 51 55 49 54 0A
//   1 byte    version (high nibble, 2) and command (low: 0 LOCAL, 1 PROXY)
//   1 byte    family (high: 0 UNSPEC, 1 INET, 2 INET6) and transport (low: 1 STREAM)
//   2 bytes   length of what follows, big-endian: the addresses, then TLVs (ignored)
//   INET:     source 4, destination 4, source port 2, destination port 2
//   INET6:    source 16, destination 16, source port 2, destination port 2
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "server/net/asio.hpp"

namespace vox::net {

inline constexpr size_t kProxyHeadBytes = 16;
inline constexpr size_t kMaxProxyRestBytes = 512;  // addresses and a few TLVs; more is refused

// How many bytes follow the 16-byte head, or nullopt (`why` says) when it is not the head
// of a version 2 header voxeld takes.
std::optional<size_t> proxy_v2_rest(std::span<const uint8_t, kProxyHeadBytes> head,
                                    std::string& why);

struct ProxyClient {
  // The client's address; nullopt for a LOCAL connection (the proxy's own, e.g. a health
  // check) or an UNSPEC family: the connection's own address stands.
  std::optional<boost::asio::ip::address> address;
};
// The header whole (head, then `rest` bytes): nullopt (`why` says) when it is not valid.
std::optional<ProxyClient> parse_proxy_v2(std::span<const uint8_t, kProxyHeadBytes> head,
                                          std::span<const uint8_t> rest, std::string& why);

}  // namespace vox::net
