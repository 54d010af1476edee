// libFuzzer target for the mesh decoder and the zstd frame reader.
// Build: cmake -S . -B build-fuzz -DCMAKE_CXX_COMPILER=clang++ -DVOXEL_FUZZ=ON
//        cmake --build build-fuzz --target mesh_decode_fuzzer
// Run:   build-fuzz/bin/mesh_decode_fuzzer -max_total_time=60
// The first input byte picks the path: raw encoding (with its CRC as given, or fixed up
// so that the structural checks behind it are reached), full frame, or delta against a
// fixed base; the rest is the input.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "proto/crc32c.hpp"
#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static vox::proto::ZstdCodec zstd;
  static vox::proto::CodecScratch scratch;
  static vox::mesh::ChunkMesh mesh;
  static const std::vector<uint8_t> base(300, 0x5A);
  const std::span<const uint8_t> input(data + 1, size - 1);
  const vox::proto::DecodeLimits limits{.max_encoding_bytes = 1 << 20};
  switch (data[0] % 4) {
    case 0:
      (void)vox::proto::decode_mesh(input, limits, scratch, mesh);
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
    default: {
      auto encoding = zstd.decompress(
          input, data[0] % 4 == 2 ? std::span<const uint8_t>(base) : std::span<const uint8_t>(),
          limits.max_encoding_bytes);
      if (encoding) (void)vox::proto::decode_mesh(*encoding, limits, scratch, mesh);
    }
  }
  return 0;
}
