// client/chunk_cache: the chunks a client holds, full meshes and deltas applied to them,
// and what happens to a chunk when a payload does not apply.
#include "client/chunk_cache.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/padded_block.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/alloc_counter.hpp"

namespace vox::client {
namespace {

// Encodings of three surface chunks: stand-ins for three versions of one chunk (a delta
// works between any two encodings).
std::vector<proto::Bytes> surface_encodings() {
  const world::TerrainGenerator gen(3);
  world::ChunkMap map;
  for (int z = -2; z <= 1; ++z)
    for (int y = -3; y <= 1; ++y)
      for (int x = -1; x <= 2; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  std::vector<proto::Bytes> out;
  mesh::PaddedBlock block;
  mesh::MeshScratch topology;
  proto::CodecScratch scratch;
  mesh::ChunkMesh mesh;
  for (int x = 0; x <= 1 && out.size() < 3; ++x)
    for (int z = -1; z <= 0 && out.size() < 3; ++z)
      for (int y = -2; y <= 0 && out.size() < 3; ++y) {
        mesh::gather_padded_block(map, {x, y, z}, block);
        mesh::mesh_chunk(block, topology, mesh);
        if (mesh.empty()) continue;
        out.emplace_back();
        proto::encode_mesh(mesh, topology, block.cells, scratch, out.back());
      }
  EXPECT_EQ(out.size(), 3u) << "not enough surface chunks";
  return out;
}

wire::ChunkMesh message(const ChunkKey& key, uint64_t version, uint64_t base_version,
                        const std::vector<uint8_t>& payload) {
  wire::ChunkMesh m;
  m.mutable_coord()->set_x(std::get<0>(key));
  m.mutable_coord()->set_y(std::get<1>(key));
  m.mutable_coord()->set_z(std::get<2>(key));
  m.set_version(version);
  m.set_base_version(base_version);
  m.set_payload(payload.data(), payload.size());
  return m;
}

class ChunkCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    encodings_ = surface_encodings();
    ASSERT_EQ(encodings_.size(), 3u);
  }
  std::vector<uint8_t> full(size_t v) {
    std::vector<uint8_t> frame;
    zstd_.compress(encodings_[v], {}, frame);
    return frame;
  }
  std::vector<uint8_t> delta(size_t from, size_t to) {
    std::vector<uint8_t> frame;
    zstd_.compress(encodings_[to], encodings_[from], frame);
    return frame;
  }
  std::optional<std::string> apply(const wire::ChunkMesh& m) {
    return cache_.apply(m, zstd_, scratch_, decoded_);
  }

  const ChunkKey key_{4, -2, 7};
  std::vector<proto::Bytes> encodings_;
  proto::ZstdCodec zstd_;
  proto::CodecScratch scratch_;
  mesh::ChunkMesh decoded_;
  ChunkCache cache_;
};

TEST_F(ChunkCacheTest, FullMeshIsHeldAndDecoded) {
  const auto error = apply(message(key_, 5, 0, full(0)));
  ASSERT_FALSE(error) << *error;
  ASSERT_EQ(cache_.chunks().count(key_), 1u);
  EXPECT_EQ(cache_.chunks().at(key_).version, 5u);
  EXPECT_EQ(cache_.chunks().at(key_).encoding, encodings_[0]);
  const auto expected = proto::decode_mesh(encodings_[0]);
  ASSERT_TRUE(expected);
  EXPECT_EQ(decoded_.indices, expected->indices);
  EXPECT_FALSE(decoded_.empty());
}

TEST_F(ChunkCacheTest, DeltasAgainstTheHeldVersionApplyInTurn) {
  ASSERT_FALSE(apply(message(key_, 5, 0, full(0))));
  auto error = apply(message(key_, 9, 5, delta(0, 1)));
  ASSERT_FALSE(error) << *error;
  EXPECT_EQ(cache_.chunks().at(key_).version, 9u);
  EXPECT_EQ(cache_.chunks().at(key_).encoding, encodings_[1]);
  error = apply(message(key_, 12, 9, delta(1, 2)));
  ASSERT_FALSE(error) << *error;
  EXPECT_EQ(cache_.chunks().at(key_).encoding, encodings_[2]);
  EXPECT_EQ(decoded_.indices, proto::decode_mesh(encodings_[2])->indices);
}

// The chunk is dropped, so the client asks for a full copy (Resync) instead of applying
// the next delta to a base it does not have.
TEST_F(ChunkCacheTest, DeltaAgainstAVersionNotHeldIsRefusedAndDropsTheChunk) {
  ASSERT_FALSE(apply(message(key_, 5, 0, full(0))));
  const auto error = apply(message(key_, 9, 4, delta(0, 1)));
  ASSERT_TRUE(error);
  EXPECT_NE(error->find("against version 4 but the client holds 5"), std::string::npos) << *error;
  EXPECT_EQ(cache_.chunks().count(key_), 0u);
  const auto again = apply(message(key_, 12, 9, delta(1, 2)));  // the next delta too
  ASSERT_TRUE(again);
  EXPECT_NE(again->find("holds 0"), std::string::npos) << *again;
}

TEST_F(ChunkCacheTest, DeltaForAChunkNeverHeldIsRefused) {
  ASSERT_FALSE(apply(message(key_, 5, 0, full(0))));
  const ChunkKey other{4, -2, 8};
  const auto error = apply(message(other, 9, 5, delta(0, 1)));
  ASSERT_TRUE(error);
  EXPECT_NE(error->find("but the client holds 0"), std::string::npos) << *error;
  EXPECT_EQ(cache_.chunks().count(other), 0u);
  EXPECT_EQ(cache_.chunks().at(key_).version, 5u) << "another chunk is untouched";
}

// The right version number over the wrong bytes (a client bug, or corruption): the
// expanded encoding fails its checks and the chunk is dropped, never held as garbage.
TEST_F(ChunkCacheTest, DeltaOverTheWrongBaseBytesIsCaughtAndDropsTheChunk) {
  cache_.hold(key_, 5, encodings_[2]);  // claims version 5, holds other bytes
  const auto error = apply(message(key_, 9, 5, delta(0, 1)));
  ASSERT_TRUE(error);
  EXPECT_EQ(cache_.chunks().count(key_), 0u);
}

TEST_F(ChunkCacheTest, EmptyOrGarbagePayloadIsRefusedAndDropsTheChunk) {
  const std::vector<std::vector<uint8_t>> bad = {{}, {1, 2, 3, 4, 5, 6, 7, 8}};
  for (const auto& payload : bad) {
    ASSERT_FALSE(apply(message(key_, 5, 0, full(0))));
    const auto error = apply(message(key_, 6, 0, payload));
    ASSERT_TRUE(error) << payload.size() << " bytes";
    EXPECT_EQ(cache_.chunks().count(key_), 0u);
  }
  // A frame that decompresses but is not a mesh encoding.
  ASSERT_FALSE(apply(message(key_, 5, 0, full(0))));
  std::vector<uint8_t> not_a_mesh;
  zstd_.compress(std::vector<uint8_t>(100, 9), {}, not_a_mesh);
  EXPECT_TRUE(apply(message(key_, 6, 0, not_a_mesh)));
  EXPECT_EQ(cache_.chunks().count(key_), 0u);
}

TEST_F(ChunkCacheTest, ForgetDropsOnlyTheNamedChunks) {
  const ChunkKey a{0, 0, 0}, b{0, 0, 1}, c{-5, 3, 2};
  for (const auto& k : {a, b, c}) ASSERT_FALSE(apply(message(k, 5, 0, full(0))));
  wire::ChunkUnload u;
  auto* coord = u.add_coords();
  coord->set_z(1);
  coord = u.add_coords();  // not held: nothing happens
  coord->set_x(100);
  cache_.forget(u);
  EXPECT_EQ(cache_.chunks().count(a), 1u);
  EXPECT_EQ(cache_.chunks().count(b), 0u);
  EXPECT_EQ(cache_.chunks().count(c), 1u);
}

// hold() reuses the held encoding's capacity: once warm, applying a delta allocates
// nothing (500 simulated players apply every message).
TEST_F(ChunkCacheTest, ApplyingToAWarmCacheAllocatesNothing) {
  ASSERT_FALSE(apply(message(key_, 1, 0, full(0))));
  std::vector<wire::ChunkMesh> messages;
  for (uint64_t v = 2; v <= 7; ++v) {
    const size_t from = (v - 2) % 2, to = (v - 1) % 2;  // 0 -> 1 -> 0 -> ...
    messages.push_back(message(key_, v, v - 1, delta(from, to)));
  }
  ASSERT_FALSE(apply(messages[0]));
  ASSERT_FALSE(apply(messages[1]));  // warm: buffers sized for both encodings
  const size_t before = test::allocations_on_this_thread();
  for (size_t i = 2; i < messages.size(); ++i) {
    const auto error = apply(messages[i]);
    ASSERT_FALSE(error) << *error;
  }
  EXPECT_EQ(test::allocations_on_this_thread() - before, 0u);
  EXPECT_EQ(cache_.chunks().at(key_).version, 7u);
}

}  // namespace
}  // namespace vox::client
