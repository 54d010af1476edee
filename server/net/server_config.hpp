// What voxeld's network side is set to: where it listens, its caps, budgets, timeouts and
// identity rules. Filled once from the flags (server/daemon), then shared read-only by the
// server and every session.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "server/auth/player_token.hpp"
#include "server/net/http_config.hpp"

namespace vox::net {

struct ServerConfig {
  std::string bind = "127.0.0.1";
  uint16_t port = 7777;
  size_t max_clients = 256;                // players (past Hello)
  size_t max_handshaking = 64;             // connections before Hello, not counted in max_clients
  size_t max_per_address = 16;             // connections from one address (0: no cap)
  size_t max_handshaking_per_address = 4;  // of them before Hello (0: no cap)
  // Addresses (address_text, matched exactly) of proxies in front of the TCP port (HAProxy
  // with send-proxy-v2, docs/haproxy-cluster.cfg): a connection from one begins with a
  // PROXY protocol v2 header (proxy_header.hpp) and its player is the client it names,
  // capped by that client's address. A connection from one without the header is closed.
  std::vector<std::string> tcp_proxies;
  uint32_t max_view_radius = 12;  // chunks
  // Level of detail (SetView.lod_level, lod_distance): the coarsest level a view may ask
  // for (at most the pipeline's lod.levels - 1; 0: none) and the largest split distance.
  uint32_t max_lod_level = 6;
  float max_lod_distance = 2.0f;
  size_t max_frame_bytes = 64 * 1024;       // largest client frame accepted
  size_t max_bytes_in_flight = 256 * 1024;  // per session, in one write
  // Queued results/errors before a client counts as not reading.
  size_t max_control_bytes = 1 << 20;
  size_t max_edits_in_flight = 256;  // a client's edits queued in the pipeline at once
  size_t max_resync_chunks = 64;     // coordinates in one Resync
  // Queries (docs/PROTOCOL.md 4.13): a ray's length, a SampleQuery's samples, a client's
  // queries waiting at once (their answers fit max_control_bytes), and its rate (a burst
  // of twice as many; <= 0: unlimited).
  float max_query_distance = 512;
  uint32_t max_query_samples = 32 * 32 * 32;
  size_t max_queries_in_flight = 8;
  double query_rate = 20;
  std::chrono::milliseconds handshake_timeout{5000};
  std::chrono::milliseconds idle_timeout{60000};   // nothing received for this long: disconnect
  std::chrono::milliseconds write_timeout{10000};  // a write not finished in this time: disconnect
  std::chrono::milliseconds frame_timeout{10000};  // a started frame not finished in this time
  // Budgets (token buckets; rate <= 0: unlimited). An edit costs the samples its box
  // touches (a 64^3 stamp: 274,625). The edit budget is per player id (shared by its
  // connections; per connection on an open server); these are the player role's limits,
  // an admin's below, and a token may carry its own.
  double edit_budget_rate = 300000;   // samples per second
  double edit_budget_burst = 600000;  // samples
  double admin_edit_budget_rate = 0;  // 0: unlimited
  double admin_edit_budget_burst = 0;
  // Every publication told to the sessions at once, not gathered while the last fan-out is
  // unhandled (publish_coalescer.hpp): for comparison.
  bool publish_at_once = false;
  double set_view_rate = 2;  // per second; more are coalesced into the newest
  double set_view_burst = 4;
  double message_rate = 200;  // messages per second; over it the session stops reading
  double message_burst = 400;
  double protocol_error_rate = 5;  // kept-connection errors per second; over it: closed
  double protocol_error_burst = 20;
  std::string server_version = "voxeld 0.2.0";
  // Identity (docs/PROTOCOL.md 4.8): with a key, Hello must carry a token it signed;
  // without one the server is open and every player has `open_role`.
  std::optional<auth::PublicKey> auth_key;
  auth::Role open_role = auth::Role::kPlayer;
  // The HTTP port (the viewer and WebSocket at /ws; http_front.hpp); none: off.
  // `http_port_required`: set explicitly, so a port that cannot be bound stops the start.
  std::optional<HttpConfig> http;
  bool http_port_required = false;
};

}  // namespace vox::net
