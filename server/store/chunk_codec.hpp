// A modified chunk's samples as the world store keeps them, zstd-compressed. Decoding
// never trusts the bytes: the frame must declare exactly the size of a chunk's arrays.
//
// Layout: u8 format (1), u8 kind; kind 0 (uniform): i16 density, u8 material (5 bytes in
// all); kind 1 (full): one zstd frame of the 32^3 densities (int16, little-endian, index
// x + 32·(y + 32·z)) followed by the 32^3 materials (98,304 bytes before compression).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "server/world/chunk.hpp"

struct ZSTD_CCtx_s;

namespace vox::store {

inline constexpr uint8_t kChunkFormat = 1;

// Encodes one chunk after another with one compression context and buffer: a checkpoint
// encodes thousands, and a fresh zstd context per chunk costs more than the chunk. Not
// thread-safe: one per thread.
class ChunkEncoder {
 public:
  ChunkEncoder();
  ~ChunkEncoder();
  ChunkEncoder(const ChunkEncoder&) = delete;
  ChunkEncoder& operator=(const ChunkEncoder&) = delete;
  std::vector<uint8_t> encode(const world::Chunk& chunk);

 private:
  ZSTD_CCtx_s* ctx_;
  std::vector<uint8_t> raw_;
};

std::vector<uint8_t> encode_chunk(const world::Chunk& chunk);  // a one-off ChunkEncoder
std::optional<world::Chunk> decode_chunk(std::span<const uint8_t> bytes,
                                         std::string* error = nullptr);

}  // namespace vox::store
