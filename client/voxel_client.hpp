// A small client for voxeld: connect, handshake, send, receive with deadlines, and keep
// per-chunk state (the encoding held for each chunk, to apply deltas). Shared by
// voxel-cli, voxel-loadtest and the integration tests. Single-threaded: one client per
// thread.
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "client/asio.hpp"
#include "client/chunk_cache.hpp"
#include "proto/framing.hpp"
#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "voxel.pb.h"

namespace vox::client {

using Clock = std::chrono::steady_clock;

class Client {
 public:
  Client();
  ~Client();
  // Throws std::runtime_error with a one-line reason on failure.
  void connect(const std::string& host, uint16_t port, std::chrono::milliseconds timeout);
  // Sends Hello and waits for Welcome (throws on Error, close or timeout).
  // `token`: a signed player token, for a server that checks them (docs/PROTOCOL.md 4.8).
  wire::Welcome handshake(const std::string& name, std::chrono::milliseconds timeout,
                          const std::string& token = {});

  void send(const wire::Envelope& message);
  void send_raw(std::span<const uint8_t> bytes);  // for tests of hostile input
  // The next message, or nullopt when the deadline passes or the connection closes.
  std::optional<wire::Envelope> receive(std::chrono::milliseconds timeout);
  bool closed() const { return closed_; }

  // Applies a ChunkMesh (full or delta) to the per-chunk state; returns an error message
  // when the payload does not decode (wrong base, corruption).
  std::optional<std::string> apply(const wire::ChunkMesh& m);
  void forget(const wire::ChunkUnload& u);
  // Receives until the ViewReady of `view_id` (PROTOCOL.md 4.2 item 5), applying meshes
  // and unloads on the way; throws on an Error, a mesh that does not apply, a close, or
  // when `timeout` passes first.
  wire::ViewReady receive_view(uint64_t view_id, std::chrono::milliseconds timeout);
  const HeldChunks& chunks() const { return cache_.chunks(); }  // level 0
  // Level-of-detail chunks held, by level (>= 1; none: an empty map).
  const HeldChunks& lod_chunks(uint32_t level) const;

 private:
  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_;
  proto::FrameDecoder decoder_{64 << 20};
  std::array<uint8_t, 64 * 1024> buffer_;
  bool closed_ = false;
  proto::ZstdCodec zstd_;
  proto::CodecScratch scratch_;
  mesh::ChunkMesh decoded_;
  ChunkCache cache_;
  std::map<uint32_t, ChunkCache> lod_cache_;  // levels >= 1
};

wire::Envelope make_hello(const std::string& name, uint32_t version = 1,
                          const std::string& token = {});
// `lod_level` > 0: a level-of-detail view of levels 0 .. lod_level (docs/PROTOCOL.md 4.10).
wire::Envelope make_set_view(float x, float y, float z, uint32_t radius, uint64_t view_id = 0,
                             uint32_t lod_level = 0, float lod_distance = 0);
wire::Envelope make_resync(std::span<const wire::ChunkCoord> coords, uint32_t level = 0);
// An Edit carrying a Brush at (x, y, z) that keeps the existing material (material 0).
wire::Envelope make_brush(uint64_t request_id, float x, float y, float z, float radius,
                          float strength, bool remove);

}  // namespace vox::client
