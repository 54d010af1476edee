// libFuzzer target for the mesh decoder and the zstd frame reader: what a client does with
// a ChunkMesh payload. scripts/fuzz.sh builds and runs it (README, "Fuzzing").
// The first input byte picks the path: raw encoding (with its CRC as given, or fixed up
// so that the structural checks behind it are reached), full frame, delta against a
// real encoding (fuzz_meshes.hpp), decompressed into a reused buffer as the client
// library does, or byte changes to a real level-of-detail (format 2) encoding, its CRC
// fixed up; the rest is the input.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "proto/crc32c.hpp"
#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "tests/fuzz/fuzz_meshes.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static vox::proto::ZstdCodec zstd;
  static vox::proto::CodecScratch scratch;
  static vox::mesh::ChunkMesh mesh;
  static vox::mesh::Buffer<uint8_t> expanded;
  static const vox::proto::Bytes base =
      vox::fuzz::sphere_encoding(vox::fuzz::kBaseRadius, vox::fuzz::kBaseMaterial);
  const std::span<const uint8_t> input(data + 1, size - 1);
  const vox::proto::DecodeLimits limits{.max_encoding_bytes = 1 << 20};
  switch (data[0] % 5) {
    case 0:
      (void)vox::proto::decode_mesh(input, limits, scratch, mesh);
      break;
    case 1: {
      auto encoding = zstd.decompress(input, {}, limits.max_encoding_bytes);
      if (encoding) (void)vox::proto::decode_mesh(*encoding, limits, scratch, mesh);
      break;
    }
    case 2:
      if (!zstd.decompress_into(input, base, limits.max_encoding_bytes, expanded))
        (void)vox::proto::decode_mesh(expanded, limits, scratch, mesh);
      break;
    case 3: {
      std::vector<uint8_t> fixed(input.begin(), input.end());
      if (fixed.size() >= 4) {
        const uint32_t crc = vox::proto::crc32c(fixed.data(), fixed.size() - 4);
        for (int i = 0; i < 4; ++i)
          fixed[fixed.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
      }
      (void)vox::proto::decode_mesh(fixed, limits, scratch, mesh);
      break;
    }
    case 4: {  // (u16 offset, xor byte) triples applied to the level-of-detail seed
      static const vox::proto::Bytes lod = vox::fuzz::lod_sphere_encoding();
      std::vector<uint8_t> changed(lod);
      for (size_t i = 0; i + 3 <= input.size(); i += 3) {
        const size_t at = (input[i] | static_cast<size_t>(input[i + 1]) << 8) % changed.size();
        changed[at] ^= input[i + 2];
      }
      const uint32_t crc = vox::proto::crc32c(changed.data(), changed.size() - 4);
      for (int i = 0; i < 4; ++i)
        changed[changed.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
      (void)vox::proto::decode_mesh(changed, limits, scratch, mesh);
      break;
    }
  }
  return 0;
}
