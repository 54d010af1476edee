#include "client-cli/chunk_cache.hpp"

namespace vox::client {

std::optional<std::string> ChunkCache::apply(const wire::ChunkMesh& m, proto::ZstdCodec& zstd,
                                             proto::CodecScratch& scratch, mesh::ChunkMesh& decoded) {
  const ChunkKey key{m.coord().x(), m.coord().y(), m.coord().z()};
  HeldChunk& held = chunks_[key];
  const std::span<const uint8_t> payload(reinterpret_cast<const uint8_t*>(m.payload().data()), m.payload().size());
  std::span<const uint8_t> base;
  if (m.base_version() != 0) {
    if (held.version != m.base_version()) {
      const std::string error = "delta against version " + std::to_string(m.base_version()) + " but the client holds " +
                                std::to_string(held.version);
      chunks_.erase(key);
      return error;
    }
    base = held.encoding;
  }
  auto encoding = zstd.decompress(payload, base, proto::DecodeLimits{}.max_encoding_bytes);
  if (!encoding) {
    chunks_.erase(key);
    return encoding.error();
  }
  if (auto error = proto::decode_mesh(*encoding, {}, scratch, decoded)) {
    chunks_.erase(key);
    return error->message;
  }
  held.version = m.version();
  held.encoding = std::move(*encoding);
  return std::nullopt;
}

void ChunkCache::forget(const wire::ChunkUnload& u) {
  for (const auto& c : u.coords()) chunks_.erase(ChunkKey{c.x(), c.y(), c.z()});
}

}  // namespace vox::client
