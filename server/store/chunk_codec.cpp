#include "server/store/chunk_codec.hpp"

#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cstring>

namespace vox::store {
namespace {

static_assert(std::endian::native == std::endian::little, "the chunk format is little-endian");
constexpr size_t kDensityBytes = world::kChunkVolume * sizeof(world::Density);
constexpr size_t kRawBytes = kDensityBytes + world::kChunkVolume;
// Level 3 (zstd's default): a surface chunk in about 60 us with a reused context, 5-15x
// smaller.
constexpr int kLevel = 3;

}  // namespace

ChunkEncoder::ChunkEncoder() : ctx_(ZSTD_createCCtx()), raw_(kRawBytes) {
  if (!ctx_) throw std::bad_alloc();
}

ChunkEncoder::~ChunkEncoder() { ZSTD_freeCCtx(ctx_); }

std::vector<uint8_t> ChunkEncoder::encode(const world::Chunk& chunk) {
  if (chunk.is_uniform()) {
    const world::Sample s = chunk.uniform_value();
    const auto d = static_cast<uint16_t>(s.density);
    return {kChunkFormat, 0, static_cast<uint8_t>(d), static_cast<uint8_t>(d >> 8), s.material};
  }
  std::memcpy(raw_.data(), chunk.densities(), kDensityBytes);
  std::memcpy(raw_.data() + kDensityBytes, chunk.materials(), world::kChunkVolume);
  std::vector<uint8_t> out(2 + ZSTD_compressBound(kRawBytes));
  out[0] = kChunkFormat;
  out[1] = 1;
  const size_t n =
      ZSTD_compressCCtx(ctx_, out.data() + 2, out.size() - 2, raw_.data(), raw_.size(), kLevel);
  if (ZSTD_isError(n)) throw std::runtime_error(ZSTD_getErrorName(n));  // cannot happen: bound
  out.resize(2 + n);
  out.shrink_to_fit();  // kept by the checkpoint until written
  return out;
}

std::vector<uint8_t> encode_chunk(const world::Chunk& chunk) {
  return ChunkEncoder().encode(chunk);
}

std::optional<world::Chunk> decode_chunk(std::span<const uint8_t> bytes, std::string* error) {
  auto fail = [error](std::string why) -> std::optional<world::Chunk> {
    if (error) *error = std::move(why);
    return std::nullopt;
  };
  if (bytes.size() < 2) return fail("chunk record shorter than its header");
  if (bytes[0] != kChunkFormat) return fail("chunk record of an unknown format");
  if (bytes[1] == 0) {
    if (bytes.size() != 5) return fail("uniform chunk record of the wrong length");
    const auto d = static_cast<world::Density>(uint16_t{bytes[2]} | uint16_t{bytes[3]} << 8);
    if (d < world::kDensityMin) return fail("chunk record with a density out of range");
    return world::Chunk(world::Sample{d, bytes[4]});
  }
  if (bytes[1] != 1) return fail("chunk record of an unknown kind");
  const auto frame = bytes.subspan(2);
  const unsigned long long size = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (size != kRawBytes) return fail("chunk record whose frame does not declare a chunk's size");
  std::vector<uint8_t> raw(kRawBytes);
  const size_t n = ZSTD_decompress(raw.data(), raw.size(), frame.data(), frame.size());
  if (ZSTD_isError(n)) return fail(std::string("chunk record: ") + ZSTD_getErrorName(n));
  if (n != kRawBytes) return fail("chunk record shorter than a chunk");
  world::Chunk chunk;
  world::Density* densities = chunk.densities();  // expands once
  std::memcpy(densities, raw.data(), kDensityBytes);
  std::memcpy(chunk.materials(), raw.data() + kDensityBytes, world::kChunkVolume);
  if (std::any_of(densities, densities + world::kChunkVolume,
                  [](world::Density d) { return d < world::kDensityMin; }))
    return fail("chunk record with a density out of range");
  chunk.compact();
  return chunk;
}

}  // namespace vox::store
