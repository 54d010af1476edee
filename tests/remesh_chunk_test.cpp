// The pipeline's per-chunk re-mesh (server/pipeline/remesh.hpp remesh_chunk): a mesh
// that did not change is not published and, once the worker is warm, allocates nothing.
#include <gtest/gtest.h>

#include <cmath>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/pipeline/remesh.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/alloc_counter.hpp"

namespace vox::pipeline {
namespace {

// The chunk the surface crosses at (16, 16) of seed 17, with its 26 neighbours.
struct SurfaceChunk {
  world::ChunkMap chunks;
  world::ChunkCoord c;
  SurfaceChunk() {
    const world::TerrainGenerator gen(17);
    c = {0,
         world::floor_div(static_cast<int>(std::floor(gen.height_at(16, 16))), world::kChunkSize),
         0};
    world::for_each_chunk_in(c.offset(-1, -1, -1), c.offset(1, 1, 1),
                             [&](world::ChunkCoord n) { chunks.insert(n, gen.generate(n)); });
  }
};

// Issue 15: every dirty chunk was meshed into a freshly allocated MeshVersion, changed or
// not; the worker's warm buffers now take the mesher's writes.
TEST(RemeshChunk, ReMeshingAChunkWhoseMeshDidNotChangeAllocatesNothing) {
  SurfaceChunk at;
  world::ChunkMap& chunks = at.chunks;
  const world::ChunkCoord c = at.c;
  MeshWorker w;
  std::shared_ptr<MeshVersion> first = remesh_chunk(w, chunks, c, nullptr);
  ASSERT_TRUE(first);
  ASSERT_GT(first->triangles, 0u);
  EXPECT_FALSE(first->full_frame.empty());
  ASSERT_FALSE(remesh_chunk(w, chunks, c, first.get()));  // warm
  const size_t before = test::allocations_on_this_thread();
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(remesh_chunk(w, chunks, c, first.get()));
  EXPECT_EQ(test::allocations_on_this_thread(), before);
}

// Under 200 LOD views, compressing a full frame of every re-mesh was 8 % of the pipeline's
// time, and clients holding a chunk take deltas: a re-mesh's full frame is made when
// first asked for, once.
TEST(RemeshChunk, AReMeshMakesItsFullFrameOnlyWhenAskedAndOnce) {
  SurfaceChunk at;
  world::ChunkMap& chunks = at.chunks;
  const world::ChunkCoord c = at.c;
  MeshWorker w;
  std::shared_ptr<MeshVersion> first = remesh_chunk(w, chunks, c, nullptr);
  ASSERT_TRUE(first);
  world::Chunk* chunk = chunks.find(c);
  world::Density* d = chunk->densities();
  for (int i = 0; i < world::kChunkSize * world::kChunkSize * world::kChunkSize; ++i)
    d[i] = static_cast<world::Density>(-d[i]);
  std::shared_ptr<MeshVersion> second = remesh_chunk(w, chunks, c, first.get());
  ASSERT_TRUE(second);
  EXPECT_TRUE(second->full_frame.empty()) << "not made at publication";
  MeshStore store;
  store.publish(second);
  const size_t before = store.memory_bytes();
  const std::span<const uint8_t> full = second->full();
  EXPECT_EQ(second->full().data(), full.data()) << "made once";
  EXPECT_GT(store.memory_bytes(), before) << "its bytes are accounted";
  proto::ZstdCodec zstd;
  const auto decoded = zstd.decompress(full, {}, size_t{1} << 22);
  ASSERT_TRUE(decoded);
  EXPECT_EQ(*decoded, second->encoding);
  EXPECT_EQ(first->full().data(), first->full_frame.data()) << "made at publication";
}

// Issue 39: at 1,000 players the network thread spent a tenth of its time making deltas,
// each for the first session asking. A re-mesh of a published chunk now carries its delta
// from that version, made by the meshing worker, accounted once published; one from a
// version still waiting for its append (no version number yet) is left to be asked for.
TEST(RemeshChunk, AReMeshOfAPublishedChunkCarriesItsDeltaMadeBeforePublication) {
  SurfaceChunk at;
  MeshWorker w;
  std::shared_ptr<MeshVersion> first = remesh_chunk(w, at.chunks, at.c, nullptr);
  ASSERT_TRUE(first);
  world::Density* d = at.chunks.find(at.c)->densities();
  for (int i = 0; i < 4096; ++i) d[i] = static_cast<world::Density>(-d[i]);
  std::shared_ptr<MeshVersion> unnumbered = remesh_chunk(w, at.chunks, at.c, first.get());
  ASSERT_TRUE(unnumbered);
  first->version = 1;
  std::shared_ptr<MeshVersion> second = remesh_chunk(w, at.chunks, at.c, first.get());
  ASSERT_TRUE(second);
  second->version = 2;
  MeshStore store;
  store.publish(first);
  const size_t before = store.memory_bytes();
  store.publish(second);
  // The old version's bytes leave, the new one's and its premade delta's come.
  const size_t after = store.memory_bytes();  // before anyone asked for a delta
  const auto delta = second->delta_from(*first);
  EXPECT_EQ(after, before - first->memory_bytes() + second->memory_bytes() + delta->capacity());
  EXPECT_EQ(second->delta_from(*first).get(), delta.get()) << "premade, not made again";
  proto::ZstdCodec zstd;
  const auto decoded = zstd.decompress(*delta, first->encoding, size_t{1} << 22);
  ASSERT_TRUE(decoded);
  EXPECT_EQ(*decoded, second->encoding);
  EXPECT_EQ(delta->capacity(), delta->size()) << "kept at its size, not the codec's bound";
  // Made from the unnumbered one on request: the same bytes.
  const auto asked = unnumbered->delta_from(*first);
  EXPECT_EQ(*zstd.decompress(*asked, first->encoding, size_t{1} << 22), unnumbered->encoding);
}

// 1,000 players' level-0 meshes took 220 MiB, four fifths of it the meshes' floats and
// indices kept beside their encodings (used only to see whether a re-mesh changed
// anything); the budget evicted and regenerated 18,000 chunks a minute for it. A version
// now keeps its encoding, its full frame and its triangle count.
TEST(RemeshChunk, AVersionKeepsItsEncodingAndNotTheMeshBesideIt) {
  SurfaceChunk at;
  MeshWorker w;
  std::shared_ptr<MeshVersion> v = remesh_chunk(w, at.chunks, at.c, nullptr);
  ASSERT_TRUE(v);
  ASSERT_GT(v->triangles, 500u);
  EXPECT_EQ(v->memory_bytes(),
            sizeof(MeshVersion) + v->encoding.capacity() + v->full_frame.capacity());
  EXPECT_EQ(proto::decode_mesh(v->encoding)->triangle_count(), v->triangles);
}

}  // namespace
}  // namespace vox::pipeline
