// Format 2 of the mesh encoding (docs/PROTOCOL.md §2.7): level-of-detail chunks with their
// seam vertices and triangles round-trip, hostile bytes are refused, and meshing plus
// encoding allocate nothing once warm.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

#include "proto/crc32c.hpp"
#include "proto/mesh_codec.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/world/terrain_generator.hpp"
#include "server/world/terrain_sampler.hpp"
#include "tests/alloc_counter.hpp"
#include "tests/codec_test_util.hpp"

namespace vox::proto {
namespace {

using world::LodChunk;
using world::LodSeams;

struct LodEncoded {
  mesh::ChunkMesh mesh;
  Bytes encoding;
  LodSeams seams;
};

// The chunks with a surface of a terrain layout over four levels, meshed and encoded
// (once: the tests share them).
std::vector<LodEncoded> make_terrain_layout_chunks() {
  static const world::TerrainGenerator generator(3);
  const world::TerrainSampler sampler(generator);
  world::LodLayout layout({.levels = 4, .top_radius = 1, .split_distance = 1.0});
  layout.update({40.5, generator.height_at(40, -20) + 2.0, -20.5});
  mesh::LodBlock block;
  mesh::LodScratch lod;
  CodecScratch scratch;
  std::vector<LodEncoded> out;
  for (const LodChunk& c : layout.chunks()) {
    if (c.level == 0) continue;
    LodEncoded e;
    e.seams = layout.seams(c);
    mesh::gather_lod_block(sampler, c, e.seams, block);
    mesh::mesh_lod_chunk(block, lod, e.mesh);
    if (e.mesh.empty()) continue;
    encode_lod_mesh(e.mesh, lod, scratch, e.encoding);
    out.push_back(std::move(e));
  }
  return out;
}

const std::vector<LodEncoded>& terrain_layout_chunks() {
  static const std::vector<LodEncoded> chunks = make_terrain_layout_chunks();
  return chunks;
}

TEST(LodCodec, ChunksWithAndWithoutSeamsRoundTrip) {
  size_t with_seams = 0;
  for (const LodEncoded& e : terrain_layout_chunks()) {
    ASSERT_EQ(e.encoding.at(0), kLodMeshFormat);
    auto decoded = decode_mesh(e.encoding);
    ASSERT_TRUE(decoded) << decoded.error();
    test::expect_same_mesh(e.mesh, *decoded);
    // Seam vertices are on 1/2048 of a cell: exact.
    for (size_t v = 0; v < e.mesh.vertex_count(); ++v)
      ASSERT_EQ(e.mesh.positions[v], decoded->positions[v]);
    with_seams += !e.seams.empty();
  }
  EXPECT_GT(with_seams, 5u);
}

// Every truncation, and mutations with the checksum fixed up so that the structural checks
// behind it are tried on their own: refused, or a mesh whose indices are all in range.
TEST(LodCodec, RefusesTruncatedAndMutatedEncodings) {
  const std::vector<LodEncoded>& chunks = terrain_layout_chunks();
  const LodEncoded* seamed = nullptr;
  for (const LodEncoded& e : chunks)
    if (!e.seams.empty() && e.encoding.size() < 40000) seamed = &e;
  ASSERT_NE(seamed, nullptr);
  for (size_t n = 0; n < seamed->encoding.size(); n += 1 + n / 64)
    EXPECT_FALSE(decode_mesh(std::span(seamed->encoding).first(n))) << "length " << n;
  std::mt19937 rng(9);
  for (int round = 0; round < 3000; ++round) {
    Bytes buf = seamed->encoding;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      // Mostly the header and the seam section, where format 2 differs.
      const size_t at = rng() % 2 == 0 ? rng() % 27 : buf.size() - 5 - rng() % (buf.size() / 4);
      buf[at] ^= static_cast<uint8_t>(1 + rng() % 255);
    }
    const uint32_t crc = crc32c(buf.data(), buf.size() - 4);
    for (int i = 0; i < 4; ++i) buf[buf.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
    auto m = decode_mesh(buf);
    if (m) {
      for (uint32_t index : m->indices) ASSERT_LT(index, m->vertex_count());
    }
  }
}

TEST(LodCodec, RefusesSeamsThatAreNotNormalized) {
  for (const LodEncoded& e : terrain_layout_chunks()) {
    if (e.seams.faces == 0) continue;
    Bytes buf = e.encoding;
    buf[17] = 0;  // the faces' edges left out
    buf[18] = 0;
    const uint32_t crc = crc32c(buf.data(), buf.size() - 4);
    for (int i = 0; i < 4; ++i) buf[buf.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
    auto m = decode_mesh(buf);
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().find("normalized"), std::string::npos) << m.error();
    return;
  }
  FAIL() << "no chunk with a split face";
}

// A client written from docs/PROTOCOL.md (the reference Python client) decodes format 2 to
// the same positions, triangles and materials, bit for bit.
TEST(LodCodec, ThePythonReferenceClientDecodesTheSameMesh) {
  if (std::system("/usr/bin/python3 -c 'import google.protobuf, zstandard' 2>/dev/null") != 0)
    GTEST_SKIP() << "Debian's python3-protobuf and python3-zstandard are not installed";
  const std::string dir = ::testing::TempDir();
  int compared = 0;
  for (const LodEncoded& e : terrain_layout_chunks()) {
    if (e.seams.empty() || e.mesh.triangle_count() > 20000 || compared == 3) continue;
    const std::string in = dir + "/lod_encoding.bin", out = dir + "/lod_decoded.bin";
    std::FILE* f = std::fopen(in.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(e.encoding.data(), 1, e.encoding.size(), f);
    std::fclose(f);
    const std::string cmd = "/usr/bin/python3 " + std::string(VOXEL_SOURCE_DIR) +
                            "/clients/python/tests/decode_to_raw.py " + in + " " + out;
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const auto decoded = decode_mesh(e.encoding);
    ASSERT_TRUE(decoded);
    std::FILE* r = std::fopen(out.c_str(), "rb");
    ASSERT_NE(r, nullptr);
    uint32_t counts[2] = {};
    ASSERT_EQ(std::fread(counts, 4, 2, r), 2u);
    ASSERT_EQ(counts[0], decoded->vertex_count());
    ASSERT_EQ(counts[1], decoded->triangle_count());
    std::vector<mesh::Vec3f> positions(counts[0]);
    std::vector<uint32_t> indices(3 * size_t{counts[1]});
    std::vector<uint8_t> materials(counts[0]);
    ASSERT_EQ(std::fread(positions.data(), sizeof(mesh::Vec3f), counts[0], r), counts[0]);
    ASSERT_EQ(std::fread(indices.data(), 4, indices.size(), r), indices.size());
    ASSERT_EQ(std::fread(materials.data(), 1, materials.size(), r), materials.size());
    std::fclose(r);
    EXPECT_TRUE(std::equal(positions.begin(), positions.end(), decoded->positions.begin()));
    EXPECT_TRUE(std::equal(indices.begin(), indices.end(), decoded->indices.begin()));
    EXPECT_TRUE(std::equal(materials.begin(), materials.end(), decoded->materials.begin()));
    ++compared;
  }
  EXPECT_EQ(compared, 3);
}

TEST(LodCodec, MeshingAndEncodingAChunkWithSeamsAllocateNothingOnceWarm) {
  const world::TerrainGenerator generator(3);
  const world::TerrainSampler sampler(generator);
  const LodChunk c{2, {0, -1, -1}};
  const LodSeams seams = world::normalized({world::kMinusX | world::kPlusY, 1u << 2});
  mesh::LodBlock block;
  mesh::LodScratch lod;
  mesh::ChunkMesh mesh;
  CodecScratch scratch;
  Bytes encoding;
  // The pipeline's way: one gather and one vertex pass, then each variant wanted.
  const LodSeams variants[] = {seams, {}, world::normalized({world::kMinusX, 0})};
  uint64_t pass = 0;
  const auto make = [&] {
    mesh::gather_lod_block(sampler, c, seams, block);
    mesh::mesh_lod_vertices(block, lod);
    ++pass;
    for (const LodSeams v : variants) {
      block.seams = v;
      mesh::mesh_lod_variant(block, lod, mesh);
      encode_lod_mesh(mesh, lod, scratch, encoding, pass);
    }
  };
  for (int warm = 0; warm < 2; ++warm) make();
  ASSERT_GT(lod.seam_vertices.size(), 0u);
  const size_t before = test::allocations_on_this_thread();
  make();
  mesh::gather_lod_block(sampler, c, seams, block);
  mesh::mesh_lod_chunk(block, lod, mesh);
  encode_lod_mesh(mesh, lod, scratch, encoding);
  EXPECT_EQ(test::allocations_on_this_thread(), before);
}

}  // namespace
}  // namespace vox::proto
