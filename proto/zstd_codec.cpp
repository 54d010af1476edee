#include "proto/zstd_codec.hpp"

#include <zstd.h>

#include <new>
#include <stdexcept>
#include <string>

namespace vox::proto {

ZstdCodec::ZstdCodec(int level, int delta_level)
    : cctx_(ZSTD_createCCtx()), dctx_(ZSTD_createDCtx()), level_(level), delta_level_(delta_level) {
  if (cctx_ == nullptr || dctx_ == nullptr) throw std::bad_alloc();
  ZSTD_DCtx_setParameter(dctx_, ZSTD_d_windowLogMax, kMaxWindowLog);
}

ZstdCodec::~ZstdCodec() {
  ZSTD_freeCCtx(cctx_);
  ZSTD_freeDCtx(dctx_);
}

void ZstdCodec::compress(std::span<const uint8_t> data, std::span<const uint8_t> base,
                         std::vector<uint8_t>& out) {
  ZSTD_CCtx_reset(cctx_, ZSTD_reset_session_and_parameters);
  ZSTD_CCtx_setParameter(cctx_, ZSTD_c_compressionLevel, base.empty() ? level_ : delta_level_);
  ZSTD_CCtx_setParameter(cctx_, ZSTD_c_contentSizeFlag, 1);
  if (!base.empty()) ZSTD_CCtx_refPrefix(cctx_, base.data(), base.size());
  out.resize(ZSTD_compressBound(data.size()));
  const size_t n = ZSTD_compress2(cctx_, out.data(), out.size(), data.data(), data.size());
  if (ZSTD_isError(n))
    throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  out.resize(n);
}

std::optional<Error> ZstdCodec::decompress_into(std::span<const uint8_t> frame,
                                                std::span<const uint8_t> base, size_t max_bytes,
                                                mesh::Buffer<uint8_t>& out) {
  out.clear();
  const unsigned long long declared = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) return Error{"not a zstd frame"};
  if (declared == ZSTD_CONTENTSIZE_UNKNOWN) return Error{"zstd frame does not declare its size"};
  if (declared > max_bytes)
    return Error{"zstd frame declares " + std::to_string(declared) + " bytes, over the limit"};
  ZSTD_DCtx_reset(dctx_, ZSTD_reset_session_only);
  if (!base.empty()) ZSTD_DCtx_refPrefix(dctx_, base.data(), base.size());
  out.resize(static_cast<size_t>(declared));
  const size_t n = ZSTD_decompressDCtx(dctx_, out.data(), out.size(), frame.data(), frame.size());
  if (ZSTD_isError(n)) return Error{std::string("zstd: ") + ZSTD_getErrorName(n)};
  if (n != declared) return Error{"zstd frame decoded to a different size than declared"};
  return std::nullopt;
}

Result<std::vector<uint8_t>> ZstdCodec::decompress(std::span<const uint8_t> frame,
                                                   std::span<const uint8_t> base,
                                                   size_t max_bytes) {
  mesh::Buffer<uint8_t> out;
  if (auto error = decompress_into(frame, base, max_bytes, out)) return *error;
  return std::vector<uint8_t>(out.begin(), out.end());
}

}  // namespace vox::proto
