// What the per-address caps count by: an IPv4 address, or an IPv6 /64 (one subscriber's
// prefix: a client owns all of it). Any thread.
#pragma once

#include <algorithm>
#include <optional>
#include <string>

#include "server/net/asio.hpp"

namespace vox::net {

// The address itself, an IPv4-mapped IPv6 one as IPv4: what a trusted proxy is matched by
// (exactly: trusting a proxy must not trust its /64).
inline std::string address_text(const boost::asio::ip::address& a) {
  namespace ip = boost::asio::ip;
  if (a.is_v6() && a.to_v6().is_v4_mapped())
    return ip::make_address_v4(ip::v4_mapped, a.to_v6()).to_string();
  return a.to_string();
}

// Whether a failed accept is for want of a resource (descriptors, buffers, memory): then
// the next one waits a little; another error (the peer's, passed on by accept) does not.
inline bool out_of_resources(const boost::system::error_code& ec) {
  namespace errc = boost::system::errc;
  return ec == boost::asio::error::no_descriptors || ec == boost::asio::error::no_buffer_space ||
         ec == boost::asio::error::no_memory || ec == errc::too_many_files_open_in_system;
}

inline std::string address_key(const boost::asio::ip::address& a) {
  namespace ip = boost::asio::ip;
  if (a.is_v6() && !a.to_v6().is_v4_mapped()) {
    auto bytes = a.to_v6().to_bytes();
    std::fill(bytes.begin() + 8, bytes.end(), 0);
    return ip::address_v6(bytes).to_string() + "/64";
  }
  return a.is_v6() ? ip::make_address_v4(ip::v4_mapped, a.to_v6()).to_string() : a.to_string();
}

// An address typed by a person or written into the bans table (docs/PROTOCOL.md 4.11):
// "203.0.113.7", "::ffff:203.0.113.7", "2001:db8::5" or "2001:db8::/64" (the key of an IPv6
// address ends so): its address_key, or nullopt when it is none of these.
inline std::optional<std::string> address_key_of(std::string text) {
  const bool prefix = text.size() > 3 && text.ends_with("/64");
  if (prefix) text.resize(text.size() - 3);
  if (text.empty() || text.size() > 64) return std::nullopt;
  boost::system::error_code ec;
  const auto a = boost::asio::ip::make_address(text, ec);
  if (ec || (prefix && (!a.is_v6() || a.to_v6().is_v4_mapped()))) return std::nullopt;
  return address_key(a);
}

}  // namespace vox::net
