#include "client/chunk_cache.hpp"

namespace vox::client {

std::optional<std::string> ChunkCache::expand(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                              mesh::Buffer<uint8_t>& out) {
  const ChunkKey key = key_of(m.coord());
  const std::span<const uint8_t> payload(reinterpret_cast<const uint8_t*>(m.payload().data()),
                                         m.payload().size());
  std::span<const uint8_t> base;
  if (m.base_version() != 0) {
    auto it = chunks_.find(key);
    const uint64_t held = it == chunks_.end() ? 0 : it->second.version;
    if (held != m.base_version()) {
      chunks_.erase(key);
      return "delta against version " + std::to_string(m.base_version()) +
             " but the client holds " + std::to_string(held);
    }
    base = it->second.encoding;
  }
  if (auto error =
          zstd.decompress_into(payload, base, proto::DecodeLimits{}.max_encoding_bytes, out)) {
    chunks_.erase(key);
    return error->message;
  }
  return std::nullopt;
}

void ChunkCache::hold(const ChunkKey& key, uint64_t version, std::span<const uint8_t> encoding) {
  HeldChunk& held = chunks_[key];
  held.version = version;
  held.encoding.assign(encoding.begin(), encoding.end());
}

std::optional<std::string> ChunkCache::apply(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                             proto::CodecScratch& scratch,
                                             mesh::ChunkMesh& decoded) {
  if (auto error = expand(m, zstd, scratch_)) return error;
  if (auto error = proto::decode_mesh(scratch_, {}, scratch, decoded)) {
    drop(key_of(m.coord()));
    return error->message;
  }
  hold(key_of(m.coord()), m.version(), scratch_);
  return std::nullopt;
}

void ChunkCache::forget(const wire::ChunkUnload& u) {
  for (const auto& c : u.coords()) chunks_.erase(ChunkKey{c.x(), c.y(), c.z()});
}

}  // namespace vox::client
