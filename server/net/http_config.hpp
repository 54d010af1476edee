// What voxeld's HTTP port is set to (http_front.hpp): where it listens, where the viewer's
// files are, which page origins may open a WebSocket, and its caps. Read-only after start.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace vox::net {

// The HTTP port's connections per address, from the game's (--max-per-address): a page
// takes a few connections, so at least 32 (0: no cap).
inline size_t http_per_address_cap(size_t game_cap) {
  return game_cap == 0 ? 0 : std::max<size_t>(32, 2 * game_cap);
}

struct HttpConfig {
  std::string bind = "127.0.0.1";
  uint16_t port = 7780;
  // The viewer's files (index.html, its bundle); empty or missing: a page saying how to
  // build it.
  std::filesystem::path root;
  std::vector<std::string> allow_origins;  // besides the page's own origin; "*": any
  // Addresses (address_text in address_key.hpp, matched exactly) of proxies in front (a
  // TLS terminator): a connection from one has no per-address HTTP cap, and its upgrade's
  // player is the client its X-Forwarded-For names. A proxied upgrade to a loopback-bound
  // server must name a loopback host or the host of one of allow_origins.
  std::vector<std::string> trusted_proxies;
  size_t max_connections = 256;  // HTTP connections open at once (0: no cap)
  size_t max_per_address = 32;   // of them from one address (0: no cap)
  std::chrono::milliseconds request_timeout{5000};
  size_t max_header_bytes = 8 * 1024;
  size_t max_file_bytes = size_t{64} << 20;  // larger files are not served (404)
  // Why this server should not take players now (a cluster node cut off from its database
  // or NATS), for GET /healthz: 200 "ok", else 503 with the reason. Null: always ok. Called
  // on the HTTP threads.
  std::function<std::optional<std::string>()> unhealthy;
};

}  // namespace vox::net
