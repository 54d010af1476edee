// zstd framing of mesh encodings: a full message is the encoding compressed; a delta is
// the new encoding compressed with the receiver's previous encoding of the same chunk as
// reference prefix (ZSTD_CCtx_refPrefix / ZSTD_DCtx_refPrefix). Contexts are reused, so
// one ZstdCodec per thread.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "proto/result.hpp"
#include "server/mesh/chunk_mesh.hpp"

struct ZSTD_CCtx_s;
struct ZSTD_DCtx_s;

namespace vox::proto {

// Full messages favour fast decoding (every client decodes each one); deltas are small,
// computed once per (chunk, base, version) and shared, so they get a stronger level.
// Level 3 rather than 7: deltas 11 % larger (7.3 % of the full message instead of 6.5 %)
// for a sixth less server CPU with 500 players (docs/PERFORMANCE.md).
inline constexpr int kDefaultZstdLevel = -1;
inline constexpr int kDefaultDeltaLevel = 3;
inline constexpr int kMaxWindowLog = 23;  // decompression never needs more than 8 MiB of window

class ZstdCodec {
 public:
  explicit ZstdCodec(int level = kDefaultZstdLevel, int delta_level = kDefaultDeltaLevel);
  ~ZstdCodec();
  ZstdCodec(const ZstdCodec&) = delete;
  ZstdCodec& operator=(const ZstdCodec&) = delete;

  // `base` empty: a full message. Otherwise a delta against `base`.
  void compress(std::span<const uint8_t> data, std::span<const uint8_t> base,
                std::vector<uint8_t>& out);
  // Refuses frames without a declared content size or declaring more than max_bytes, and
  // any frame that does not decode to exactly its declared size.
  Result<std::vector<uint8_t>> decompress(std::span<const uint8_t> frame,
                                          std::span<const uint8_t> base, size_t max_bytes);
  // The same into a caller-owned buffer (its capacity reused; nothing is zero-filled).
  std::optional<Error> decompress_into(std::span<const uint8_t> frame,
                                       std::span<const uint8_t> base, size_t max_bytes,
                                       mesh::Buffer<uint8_t>& out);

 private:
  ZSTD_CCtx_s* cctx_;
  ZSTD_DCtx_s* dctx_;
  int level_, delta_level_;
};

}  // namespace vox::proto
