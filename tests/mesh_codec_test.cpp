#include "proto/mesh_codec.hpp"

#include <gtest/gtest.h>
#include <link.h>
#include <zstd.h>

#include <bit>
#include <cmath>
#include <random>
#include <span>
#include <vector>

#include "proto/crc32c.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/gradient_noise.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/codec_test_util.hpp"

namespace vox::proto {
namespace {

using mesh::ChunkMesh;
using world::ChunkCoord;

struct Encoded {
  ChunkMesh mesh;
  Bytes encoding;
};

Encoded mesh_and_encode(const mesh::PaddedBlock& block) {
  static mesh::MeshScratch topology;
  static CodecScratch scratch;
  Encoded e;
  mesh::mesh_chunk(block, topology, e.mesh);
  encode_mesh(e.mesh, topology, block.cells, scratch, e.encoding);
  return e;
}

Encoded mesh_and_encode(const world::ChunkMap& map, ChunkCoord c) {
  static mesh::PaddedBlock block;
  mesh::gather_padded_block(map, c, block);
  return mesh_and_encode(block);
}

using test::expect_same_mesh;

world::ChunkMap terrain(uint64_t seed, int r) {
  const world::TerrainGenerator gen(seed);
  world::ChunkMap map;
  for (int z = -r - 1; z <= r; ++z)
    for (int y = -3; y <= 2; ++y)
      for (int x = -r - 1; x <= r; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  return map;
}

TEST(MeshCodec, RoundTripsTerrainChunks) {
  const world::ChunkMap map = terrain(3, 2);
  size_t non_empty = 0;
  for (int z = -2; z < 2; ++z)
    for (int y = -2; y < 2; ++y)
      for (int x = -2; x < 2; ++x) {
        const Encoded e = mesh_and_encode(map, {x, y, z});
        auto decoded = decode_mesh(e.encoding);
        ASSERT_TRUE(decoded) << decoded.error();
        expect_same_mesh(e.mesh, *decoded);
        non_empty += e.mesh.empty() ? 0 : 1;
      }
  EXPECT_GT(non_empty, 10u);
}

TEST(MeshCodec, RoundTripsWorstCaseAndExactZeros) {
  mesh::PaddedBlock block;
  const world::GradientNoise noise(3);
  std::mt19937 rng(1);
  for (int z = -1; z <= 33; ++z)
    for (int y = -1; y <= 33; ++y)
      for (int x = -1; x <= 33; ++x) {
        const int i = mesh::PaddedBlock::index(x, y, z);
        block.density[i] = world::quantize_density(
            noise.noise3(x * 0.93f + 0.31f, y * 0.87f + 0.17f, z * 0.91f + 0.53f));
        if (rng() % 7 == 0)
          block.density[i] = 0;  // samples exactly on the surface: dropped triangles
        block.material[i] = static_cast<world::Material>(1 + rng() % 200);
      }
  const Encoded e = mesh_and_encode(block);
  ASSERT_GT(e.mesh.triangle_count(), 50000u);
  const size_t table_triangles = [&] {
    mesh::MeshScratch t;
    ChunkMesh m;
    mesh::mesh_chunk(block, t, m);
    return mesh::max_triangles(t, block.cells);
  }();
  ASSERT_LT(e.mesh.triangle_count(), table_triangles)
      << "the case should include dropped triangles";
  auto decoded = decode_mesh(e.encoding);
  ASSERT_TRUE(decoded) << decoded.error();
  expect_same_mesh(e.mesh, *decoded);
}

// Exactly: decoded positions are multiples of 1/1024 in [0, 32], so scaled by 1024 they
// are integers and the cross product is exact in 64-bit integers.
bool has_zero_area(const mesh::Vec3f& a, const mesh::Vec3f& b, const mesh::Vec3f& c) {
  auto fixed = [](const mesh::Vec3f& p) {
    return std::array<int64_t, 3>{std::llround(p.x * kFractionSteps),
                                  std::llround(p.y * kFractionSteps),
                                  std::llround(p.z * kFractionSteps)};
  };
  const auto pa = fixed(a), pb = fixed(b), pc = fixed(c);
  const int64_t u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  const int64_t w[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
  return u[1] * w[2] - u[2] * w[1] == 0 && u[2] * w[0] - u[0] * w[2] == 0 &&
         u[0] * w[1] - u[1] * w[0] == 0;
}

// Issue 12 item 5: a vertex whose fraction rounds to 0 or 1024 lands on a sample, where
// other vertices may land too; the server dropped triangles by their exact positions, so
// 8 of 107,118 decoded triangles of seed 5 (radius 3 around the origin) had zero area.
TEST(MeshCodec, NoDecodedTriangleHasZeroAreaAfterQuantisation) {
  size_t triangles = 0, zero_area = 0, positions_differ = 0;
  for (uint64_t seed : {5ull, 1ull, 2ull, 12ull}) {
    const world::TerrainGenerator gen(seed);
    world::ChunkMap map;
    for (int z = -4; z <= 4; ++z)
      for (int y = -4; y <= 4; ++y)
        for (int x = -4; x <= 4; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
    for (int z = -3; z <= 3; ++z)
      for (int y = -3; y <= 3; ++y)
        for (int x = -3; x <= 3; ++x) {
          if (x * x + y * y + z * z > 9) continue;
          const Encoded e = mesh_and_encode(map, {x, y, z});
          auto decoded = decode_mesh(e.encoding);
          ASSERT_TRUE(decoded) << decoded.error();
          ASSERT_EQ(decoded->triangle_count(), e.mesh.triangle_count()) << "seed " << seed;
          ASSERT_EQ(decoded->indices, e.mesh.indices) << "seed " << seed;
          positions_differ += decoded->positions == e.mesh.positions ? 0 : 1;
          const auto& p = decoded->positions;
          const auto& idx = decoded->indices;
          for (size_t t = 0; t < idx.size(); t += 3) {
            zero_area += has_zero_area(p[idx[t]], p[idx[t + 1]], p[idx[t + 2]]) ? 1 : 0;
          }
          triangles += decoded->triangle_count();
        }
  }
  EXPECT_GT(triangles, 300000u);
  EXPECT_EQ(zero_area, 0u) << "of " << triangles << " decoded triangles";
  EXPECT_EQ(positions_differ, 0u)
      << "chunks whose decoded positions differ from the server's own mesh";
}

TEST(MeshCodec, DecodedNeighboursShareBitIdenticalFaceVertices) {
  const world::ChunkMap map = terrain(5, 1);
  for (int y = -2; y < 2; ++y) {
    const auto a = decode_mesh(mesh_and_encode(map, {0, y, 0}).encoding);
    const auto b = decode_mesh(mesh_and_encode(map, {1, y, 0}).encoding);
    ASSERT_TRUE(a && b);
    std::vector<std::array<float, 3>> fa, fb;
    for (const auto& p : a->positions)
      if (p.x == 32.0f) fa.push_back({p.x, p.y, p.z});
    for (const auto& p : b->positions)
      if (p.x == 0.0f) fb.push_back({p.x + 32.0f, p.y, p.z});
    std::sort(fa.begin(), fa.end());
    std::sort(fb.begin(), fb.end());
    EXPECT_EQ(fa, fb);
  }
}

TEST(MeshCodec, DeltaRebuildsTheNewEncodingForEveryEditType) {
  const world::TerrainGenerator gen(7);
  const std::vector<world::Edit> edits = {
      world::Brush{{16, 0, 16}, 2, 1.0f, false, world::Material{5}},
      world::Brush{{16, 0, 16}, 3, 0.8f, true, std::nullopt},
      world::Explosion{{10, 0, 20}, 5, 2},
      world::Smooth{{16, 0, 16}, 4, 1.0f},
      world::Paint{{16, 0, 16}, 4, 9},
      world::Stamp{world::Stamp::Shape::kSphere, {}, {}, {20, 0, 12}, 3, true, 4}};
  ZstdCodec zstd;
  for (size_t k = 0; k < edits.size(); ++k) {
    world::ChunkMap map;
    for (int z = -1; z <= 1; ++z)
      for (int y = -2; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
    world::Edit edit = edits[k];
    // Put the edit on the surface of chunk column (0, 0).
    std::visit(
        [&](auto& e) {
          if constexpr (requires { e.center; })
            e.center.y = gen.height_at(static_cast<int>(e.center.x), static_cast<int>(e.center.z));
        },
        edit);
    const ChunkCoord c =
        world::chunk_of_voxel(16, static_cast<int>(std::floor(gen.height_at(16, 16))), 16);
    const Encoded before = mesh_and_encode(map, c);
    for (const ChunkCoord t : world::chunks_overlapping(world::touched_box(edit))) {
      if (world::Chunk* chunk = map.find(t)) {
        std::optional<world::SampleSnapshot> snap;
        if (auto* s = std::get_if<world::Smooth>(&edit))
          snap = world::take_snapshot(map, world::smooth_read_box(*s));
        world::apply_edit(edit, t, *chunk, snap ? &*snap : nullptr);
      }
    }
    const Encoded after = mesh_and_encode(map, c);
    ASSERT_NE(before.encoding, after.encoding) << "edit " << k << " should change the chunk";
    std::vector<uint8_t> full, delta;
    zstd.compress(after.encoding, {}, full);
    zstd.compress(after.encoding, before.encoding, delta);
    EXPECT_LT(delta.size(), full.size()) << "edit " << k;
    auto rebuilt = zstd.decompress(delta, before.encoding, 1 << 22);
    ASSERT_TRUE(rebuilt) << rebuilt.error();
    EXPECT_EQ(*rebuilt, after.encoding);
    auto decoded = decode_mesh(*rebuilt);
    ASSERT_TRUE(decoded) << decoded.error();
    expect_same_mesh(after.mesh, *decoded);
    // Against the wrong base the result never decodes as a mesh.
    const Encoded other = mesh_and_encode(map, c.offset(1, 0, 0));
    auto wrong = zstd.decompress(delta, other.encoding, 1 << 22);
    if (wrong) {
      EXPECT_FALSE(decode_mesh(*wrong)) << "edit " << k;
    }
  }
}

TEST(MeshCodec, RejectsEveryTruncation) {
  const world::ChunkMap map = terrain(3, 1);
  const Encoded e = mesh_and_encode(map, {0, -1, 0});
  ASSERT_FALSE(e.mesh.empty());
  for (size_t n = 0; n < e.encoding.size(); ++n) {
    EXPECT_FALSE(decode_mesh(std::span(e.encoding).first(n))) << "length " << n;
  }
  ZstdCodec zstd;
  std::vector<uint8_t> frame;
  zstd.compress(e.encoding, {}, frame);
  for (size_t n = 0; n < frame.size(); ++n) {
    auto out = zstd.decompress(std::span(frame).first(n), {}, 1 << 22);
    EXPECT_FALSE(out && decode_mesh(*out)) << "frame length " << n;
  }
}

// `frame` with the content size its header declares rewritten to `size`. The size is the
// header's last field (RFC 8878 3.1.1.1): after the magic number, the descriptor, the
// window byte (absent in single-segment frames) and the dictionary id; in 2 bytes it is
// stored as size - 256.
std::vector<uint8_t> with_declared_size(std::vector<uint8_t> frame, uint64_t size) {
  const uint8_t descriptor = frame.at(4);
  const bool single_segment = (descriptor & 0x20) != 0;
  const size_t dictionary_id_sizes[4] = {0, 1, 2, 4};
  const size_t size_field_sizes[4] = {single_segment ? 1u : 0u, 2, 4, 8};
  const size_t field = size_field_sizes[descriptor >> 6];
  EXPECT_GT(field, 0u) << "the frame declares no size to rewrite";
  const size_t at = 5 + (single_segment ? 0 : 1) + dictionary_id_sizes[descriptor & 3];
  const uint64_t stored = field == 2 ? size - 256 : size;
  for (size_t i = 0; i < field; ++i) frame.at(at + i) = static_cast<uint8_t>(stored >> (8 * i));
  EXPECT_EQ(ZSTD_getFrameContentSize(frame.data(), frame.size()), size);
  return frame;
}

// A real zstd frame of `data` that leaves its content size out: one-shot with the content
// size flag off, or streamed in two pieces (the size is unknown when the header is written).
std::vector<uint8_t> frame_without_size(std::span<const uint8_t> data, bool streamed) {
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  std::vector<uint8_t> frame(ZSTD_compressBound(data.size()));
  size_t written = 0;
  if (!streamed) {
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
    written = ZSTD_compress2(cctx, frame.data(), frame.size(), data.data(), data.size());
    EXPECT_FALSE(ZSTD_isError(written));
  } else {
    ZSTD_outBuffer out{frame.data(), frame.size(), 0};
    ZSTD_inBuffer first{data.data(), data.size() / 2, 0};
    EXPECT_EQ(ZSTD_compressStream2(cctx, &out, &first, ZSTD_e_continue), 0u);
    ZSTD_inBuffer rest{data.data() + data.size() / 2, data.size() - data.size() / 2, 0};
    EXPECT_EQ(ZSTD_compressStream2(cctx, &out, &rest, ZSTD_e_end), 0u) << "frame not finished";
    written = out.pos;
  }
  ZSTD_freeCCtx(cctx);
  frame.resize(written);
  return frame;
}

// A bomb: 8 MiB of zeros in under 2 KB. Refused from its header, before any output exists.
TEST(ZstdCodec, RefusesAFrameDeclaringMoreThanTheLimit) {
  ZstdCodec zstd;
  std::vector<uint8_t> zeros(8 << 20, 0), frame;
  zstd.compress(zeros, {}, frame);
  EXPECT_LT(frame.size(), 2000u);
  auto r = zstd.decompress(frame, {}, DecodeLimits{}.max_encoding_bytes);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("over the limit"), std::string::npos) << r.error();
  EXPECT_TRUE(zstd.decompress(frame, {}, zeros.size())) << "the same frame within its limit";
}

// Without a declared size the output could only be bounded while decoding; the codec
// refuses such frames outright (the server always declares it).
TEST(ZstdCodec, RefusesAWellFormedFrameWithoutADeclaredSize) {
  ZstdCodec zstd;
  std::vector<uint8_t> data(5000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>(i * i % 251);
  for (const bool streamed : {false, true}) {
    const std::vector<uint8_t> frame = frame_without_size(data, streamed);
    ASSERT_EQ(ZSTD_getFrameContentSize(frame.data(), frame.size()), ZSTD_CONTENTSIZE_UNKNOWN)
        << (streamed ? "streamed" : "one-shot");
    // Well formed: plain zstd decodes it to the data.
    std::vector<uint8_t> plain(data.size());
    ASSERT_EQ(ZSTD_decompress(plain.data(), plain.size(), frame.data(), frame.size()), data.size());
    ASSERT_EQ(plain, data);
    auto r = zstd.decompress(frame, {}, 1 << 20);
    ASSERT_FALSE(r) << (streamed ? "streamed" : "one-shot");
    EXPECT_NE(r.error().find("does not declare its size"), std::string::npos) << r.error();
    // As a delta too: a base changes nothing.
    auto delta = zstd.decompress(frame, data, 1 << 20);
    ASSERT_FALSE(delta);
    EXPECT_NE(delta.error().find("does not declare its size"), std::string::npos);
  }
}

// A frame that lies about its size, either way, is refused; the limit applies to what it
// declares.
TEST(ZstdCodec, RefusesAFrameThatDecodesToOtherThanItsDeclaredSize) {
  ZstdCodec zstd;
  std::vector<uint8_t> small(1000, 7), frame;
  zstd.compress(small, {}, frame);
  EXPECT_TRUE(zstd.decompress(frame, {}, 1000));
  EXPECT_FALSE(zstd.decompress(frame, {}, 999));
  EXPECT_FALSE(zstd.decompress(with_declared_size(frame, 999), {}, 1000)) << "declares less";
  EXPECT_FALSE(zstd.decompress(with_declared_size(frame, 1001), {}, 2000)) << "declares more";
  EXPECT_TRUE(zstd.decompress(with_declared_size(frame, 1000), {}, 1000)) << "the rewrite";
  auto garbage = zstd.decompress(std::vector<uint8_t>{1, 2, 3, 4, 5, 6, 7, 8}, {}, 1000);
  ASSERT_FALSE(garbage);
  EXPECT_NE(garbage.error().find("not a zstd frame"), std::string::npos) << garbage.error();
}

// Counts in the header that cannot fit a chunk, and a format this version does not know.
TEST(MeshCodec, RefusesHeaderCountsThatCannotFitAChunkAndUnknownFormats) {
  Bytes fake(64, 0);
  fake[0] = kMeshFormat;
  fake[1] = fake[2] = fake[3] = 32;
  fake[7] = 0x7F;  // 2^30 vertices
  EXPECT_FALSE(decode_mesh(fake));
  fake[0] = 9;
  auto bad_version = decode_mesh(fake);
  ASSERT_FALSE(bad_version);
  EXPECT_NE(bad_version.error().find("unknown mesh format"), std::string::npos);
}

// Fuzz: mutated and random buffers through decompress + decode never crash or hang.
TEST(MeshCodec, SurvivesMutatedAndRandomInput) {
  const world::ChunkMap map = terrain(11, 1);
  std::vector<Bytes> seeds;
  for (int y = -2; y < 2; ++y) seeds.push_back(mesh_and_encode(map, {0, y, 0}).encoding);
  ZstdCodec zstd;
  std::mt19937 rng(123);
  size_t decoded_ok = 0;
  for (int round = 0; round < 4000; ++round) {
    Bytes buf = seeds[static_cast<size_t>(round) % seeds.size()];
    const bool compressed = round % 2 == 1;
    if (compressed) {
      Bytes frame;
      zstd.compress(buf, {}, frame);
      buf = frame;
    }
    if (round % 10 == 0) {
      buf.resize(rng() % 4096);
      for (auto& b : buf) b = static_cast<uint8_t>(rng());
    } else {
      const int flips = 1 + static_cast<int>(rng() % 8);
      for (int f = 0; f < flips && !buf.empty(); ++f)
        buf[rng() % buf.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
      if (rng() % 4 == 0 && !buf.empty()) buf.resize(rng() % buf.size());
    }
    if (compressed) {
      auto out = zstd.decompress(buf, {}, DecodeLimits{}.max_encoding_bytes);
      if (out) decoded_ok += decode_mesh(*out) ? 1 : 0;
    } else {
      decoded_ok += decode_mesh(buf) ? 1 : 0;
      // With the checksum fixed up, the structural checks behind it must hold on their own.
      if (buf.size() >= 4) {
        const uint32_t crc = crc32c(buf.data(), buf.size() - 4);
        for (int i = 0; i < 4; ++i) buf[buf.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
        auto m = decode_mesh(buf);
        if (m) {
          for (uint32_t index : m->indices) ASSERT_LT(index, m->vertex_count());
        }
      }
    }
  }
  EXPECT_LT(decoded_ok, 40u) << "the checksum should catch nearly every corruption";
}

TEST(MeshCodec, OctahedralNormalsRoundTrip) {
  std::mt19937 rng(4);
  std::normal_distribution<float> g;
  for (int i = 0; i < 20000; ++i) {
    mesh::Vec3f n{g(rng), g(rng), g(rng)};
    const float l = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    n = {n.x / l, n.y / l, n.z / l};
    const auto e = encode_normal(n);
    const auto d = decode_normal(e[0], e[1]);
    ASSERT_GT(n.x * d.x + n.y * d.y + n.z * d.z, 0.999f);
  }
}

// Normals were normalised with the processor's reciprocal-square-root estimate, whose
// bits differ between x86 processors and which no JavaScript client can reproduce. The
// bits below are PROTOCOL §2.4's float32 steps, worked out apart (Python, rounding to
// float32 after every operation).
TEST(MeshCodec, DecodedNormalsAreTheSameBitsOnEveryProcessor) {
  auto bits = [](float f) { return std::bit_cast<uint32_t>(f); };
  const struct {
    uint8_t u, v;
    uint32_t x, y, z;
  } cases[] = {{0, 0, 0x80000000, 0x80000000, 0xbf800000},
               {191, 159, 0x3f507749, 0x3eced313, 0x3ed563e9},
               {128, 128, 0x3b81848b, 0x3b81848b, 0x3f7ffefa},
               {3, 250, 0xbd2b2d32, 0x3ccd6998, 0xbf7fb21f}};
  for (const auto& c : cases) {
    const auto d = decode_normal(c.u, c.v);
    EXPECT_EQ(bits(d.x), c.x) << int{c.u} << "," << int{c.v};
    EXPECT_EQ(bits(d.y), c.y) << int{c.u} << "," << int{c.v};
    EXPECT_EQ(bits(d.z), c.z) << int{c.u} << "," << int{c.v};
  }
}

}  // namespace
}  // namespace vox::proto

namespace vox::proto {
namespace {

// The worked example of docs/PROTOCOL.md: one cell, only corner (0,0,0) solid.
TEST(MeshCodec, WorkedExampleOfTheProtocolDocument) {
  mesh::PaddedBlock block;
  block.cells = {1, 1, 1};
  for (int z = -1; z <= 33; ++z)
    for (int y = -1; y <= 33; ++y)
      for (int x = -1; x <= 33; ++x) {
        const int i = mesh::PaddedBlock::index(x, y, z);
        const bool corner = x <= 0 && y <= 0 && z <= 0;
        block.density[i] = corner ? 16384 : -16384;
        block.material[i] = corner ? 3 : 0;
      }
  const Encoded e = mesh_and_encode(block);
  const Bytes documented = {0x01, 0x01, 0x01, 0x01, 0x03, 0x00, 0x00, 0x00, 0x01, 0x00,
                            0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x03, 0x01, 0x01, 0x00,
                            0x00, 0x00, 0x02, 0x02, 0x02, 0xbf, 0x9f, 0x9f, 0x9f, 0xbf,
                            0x9f, 0x03, 0x00, 0x00, 0xe4, 0x27, 0x39, 0xaa};
  EXPECT_EQ(e.encoding, documented);
  auto m = decode_mesh(documented);
  ASSERT_TRUE(m) << m.error();
  ASSERT_EQ(m->vertex_count(), 3u);
  EXPECT_EQ(m->positions[0], (mesh::Vec3f{0.5f, 0, 0}));
  EXPECT_EQ(m->positions[1], (mesh::Vec3f{0, 0.5f, 0}));
  EXPECT_EQ(m->positions[2], (mesh::Vec3f{0, 0, 0.5f}));
  EXPECT_EQ(m->indices, (mesh::Buffer<uint32_t>{0, 1, 2}));
  EXPECT_NEAR(m->normals[0].x, 0.8165f, 0.01f);
  EXPECT_EQ(m->materials[2], 3);
}

}  // namespace
}  // namespace vox::proto

namespace vox::proto {
namespace {
// glibc carves a thread's static thread-local block out of its stack. decode_mesh kept its
// 66 KiB scratch in a thread_local, and civetweb's worker threads (the metrics endpoint)
// overflowed their small stacks: every scrape got an empty reply. This test binary links
// the same libraries whose thread-locals voxeld has (mesh, codec, world); together they
// must stay small. (voxeld's own are checked by the metrics test scraping it.)
TEST(MeshCodec, ThreadLocalsLeaveSmallThreadStacksAlone) {
  size_t tls = 0;
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        if (info->dlpi_name != nullptr && info->dlpi_name[0] != '\0') return 0;  // the executable
        for (int i = 0; i < info->dlpi_phnum; ++i)
          if (info->dlpi_phdr[i].p_type == PT_TLS)
            *static_cast<size_t*>(data) = info->dlpi_phdr[i].p_memsz;
        return 0;
      },
      &tls);
  EXPECT_LT(tls, size_t{16} << 10) << "bytes of static thread-local storage";
  EXPECT_TRUE(decode_mesh(mesh_and_encode(terrain(3, 1), {0, -1, 0}).encoding));
}

TEST(Crc32c, MatchesTheStandardCheckValue) {
  const std::string s = "123456789";
  EXPECT_EQ(crc32c(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0xE3069283u);
  EXPECT_EQ(crc32c(nullptr, 0), 0u);
}
}  // namespace
}  // namespace vox::proto
