// The pipeline with a durable store: an edit is ACCEPTED only once it is in the store;
// when the store cannot write, the batch is undone and its edits refused
// STORAGE_UNAVAILABLE, the world stays as it was, and edits are accepted again once the
// store works. A real PostgreSQL server is stopped and started under it.
#include <gtest/gtest.h>

#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "tests/postgres_server.hpp"

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;

std::vector<world::Sample> samples_around(WorldPipeline& p, int x0, int y0, int z0, int r) {
  std::vector<world::Sample> out;
  p.inspect([&](const world::ChunkMap& map) {
    for (int z = z0 - r; z <= z0 + r; ++z)
      for (int y = y0 - r; y <= y0 + r; ++y)
        for (int x = x0 - r; x <= x0 + r; ++x) out.push_back(map.sample_at(x, y, z));
  });
  return out;
}

TEST(PipelineStore, EditsTheStoreCouldNotWriteAreUndoneAndRefusedUntilItIsBack) {
  test::PostgresServer server;
  auto store = store::open_world_store(server.create_database("pipeline"), {.seed = 3});
  WorldPipeline p(PipelineConfig{
      .seed = 3, .threads = 2, .store = store.get(), .store_retry = std::chrono::milliseconds(50)});
  const world::TerrainGenerator gen(3);
  const int y = static_cast<int>(gen.height_at(10, 10));
  p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {0, y / 32 + 1, 0}}).get();
  const EditResult first = p.submit(world::Explosion{{10, float(y), 10}, 4, 1}).get();
  ASSERT_TRUE(first.accepted) << first.message;
  const auto before = samples_around(p, 10, y, 10, 8);
  const uint64_t published = p.stats().meshes_published;

  server.stop();
  const EditResult refused = p.submit(world::Explosion{{12, float(y), 10}, 6, 1.5f}).get();
  EXPECT_FALSE(refused.accepted);
  EXPECT_EQ(refused.reason, world::RefusalReason::kStorageUnavailable);
  EXPECT_TRUE(refused.changed_chunks.empty());
  EXPECT_EQ(samples_around(p, 10, y, 10, 8), before) << "a refused edit changed the world";
  EXPECT_EQ(p.stats().meshes_published, published) << "a refused edit published a mesh";
  // While the store rests, edits are refused without a try.
  EXPECT_EQ(p.submit(world::Brush{{10, float(y), 10}, 3}).get().reason,
            world::RefusalReason::kStorageUnavailable);

  server.start();
  std::this_thread::sleep_for(60ms);  // past store_retry
  const EditResult again = p.submit(world::Explosion{{12, float(y), 10}, 6, 1.5f}).get();
  EXPECT_TRUE(again.accepted) << again.message;
  EXPECT_NE(samples_around(p, 10, y, 10, 8), before);
  // The log holds exactly the accepted edits, with increasing sequence numbers.
  std::vector<uint64_t> seqs;
  store->for_each_edit(0, [&](const store::LoggedEdit& e) {
    seqs.push_back(e.seq);
    return true;
  });
  ASSERT_EQ(seqs.size(), 2u);
  EXPECT_LT(seqs[0], seqs[1]);
}

}  // namespace
}  // namespace vox::pipeline
