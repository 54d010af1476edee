// Counters and histograms the sessions, the server and the pipeline observer bump; the
// stats line and the metrics endpoint read them. Any thread (relaxed atomics).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "server/net/latency_histogram.hpp"

namespace vox::net {

enum class RefusedBy : uint8_t {
  kHandshakesFull,
  kAddressFull,
  kServerFull,
  kToken,
  kBanned,
  kCount
};
enum class DroppedBy : uint8_t { kSlowReader, kWriteTimeout, kCount };
// WebSocket connections closed for breaking the transport's rules (ws_connection.hpp).
enum class WsClosedBy : uint8_t { kTooBig, kText, kPingFlood, kFrameTimeout, kProtocol, kCount };
// HTTP requests answered with an error, or connections closed before a request was whole
// (http_front.hpp).
enum class HttpRefusedBy : uint8_t {
  kBadRequest,    // 400: unparsable, a body, a path that leaves the static root
  kNotFound,      // 404
  kBadMethod,     // 405: not GET or HEAD
  kHeaderTooBig,  // 431
  kOrigin,        // 403: an upgrade from an origin not allowed
  kBusy,          // 503: over the HTTP connection caps
  kTimeout,       // the request (or the upgrade) not complete in time: closed
  kCount
};

struct ServerCounters {
  using Counter = std::atomic<uint64_t>;
  static constexpr size_t kStatuses = 16;    // EditResult.Status values
  static constexpr size_t kErrorCodes = 22;  // Error.Code values

  Counter players{0};      // gauge: sessions past Hello
  Counter handshaking{0};  // gauge: connections before Hello
  Counter edits{0};
  Counter queries{0};  // raycast, ground and sample queries passed on to the pipeline
  Counter meshes_sent{0};
  Counter deltas_sent{0};
  static constexpr size_t kLevels = 7;  // mesh levels 0..6
  // ChunkMesh payload bytes and messages by level, [0] full copies and [1] deltas.
  std::array<std::array<Counter, 2>, kLevels> mesh_bytes{};
  std::array<std::array<Counter, 2>, kLevels> mesh_messages{};
  Counter bytes_sent{0};
  Counter messages_sent{0};
  Counter disconnects{0};
  Counter set_views_coalesced{0};
  Counter reads_paused{0};                        // times a session stopped reading (message rate)
  Counter chunks_resynced{0};                     // chunks clients asked for again in full (Resync)
  std::array<Counter, kStatuses> edit_results{};  // by EditResult.Status
  std::array<Counter, kErrorCodes> errors_sent{};  // by Error.Code
  std::array<Counter, static_cast<size_t>(RefusedBy::kCount)> refused{};
  std::array<Counter, static_cast<size_t>(DroppedBy::kCount)> dropped{};
  std::array<Counter, static_cast<size_t>(WsClosedBy::kCount)> ws_closed{};
  std::array<Counter, static_cast<size_t>(HttpRefusedBy::kCount)> http_refused{};
  Counter http_requests{0};  // answered, whatever the status
  Counter ws_upgrades{0};    // WebSocket connections accepted
  Counter session_bytes{0};  // gauge: sessions' accounted memory

  LatencyHistogram edit_to_publish;        // submit -> the pipeline's result (meshes published)
  LatencyHistogram edit_to_delta_written;  // submit -> a delta showing it written to a socket
  LatencyHistogram batch_duration;
  LatencyHistogram remesh_duration;
  LatencyHistogram store_commit;       // a transaction of the edit log (one batch's or more)
  LatencyHistogram store_commit_wait;  // per batch: how long the pipeline stood waiting for it
  Counter store_commits{0}, store_committed_edits{0}, store_failures{0};
  LatencyHistogram checkpoint_duration;  // a checkpoint's compression and transaction
  Counter checkpoint_bytes{0};           // chunk records written by checkpoints

  static void bump(Counter& c) { c.fetch_add(1, std::memory_order_relaxed); }
};

}  // namespace vox::net
