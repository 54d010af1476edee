// What the per-address caps count by: an IPv4 address, or an IPv6 /64 (one subscriber's
// prefix: a client owns all of it). Any thread.
#pragma once

#include <algorithm>
#include <string>

#include "server/net/asio.hpp"

namespace vox::net {

inline std::string address_key(const boost::asio::ip::address& a) {
  namespace ip = boost::asio::ip;
  if (a.is_v6() && !a.to_v6().is_v4_mapped()) {
    auto bytes = a.to_v6().to_bytes();
    std::fill(bytes.begin() + 8, bytes.end(), 0);
    return ip::address_v6(bytes).to_string() + "/64";
  }
  return a.is_v6() ? ip::make_address_v4(ip::v4_mapped, a.to_v6()).to_string() : a.to_string();
}

}  // namespace vox::net
