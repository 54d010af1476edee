// The pipeline with a durable store: an edit is ACCEPTED only once it is in the store;
// when the store cannot write, the batch is undone and its edits refused
// STORAGE_UNAVAILABLE, the world stays as it was, and edits are accepted again once the
// store works. A real PostgreSQL server is stopped and started under it.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/world_store.hpp"
#include "tests/pipeline_test_util.hpp"
#include "tests/postgres_server.hpp"
#include "tests/temp_dir.hpp"

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;

using test::eventually;
using test::samples_around;

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

// Edits over chunk borders, a smooth among them (it reads its neighbours' samples).
std::vector<world::Edit> border_edits(int y) {
  const float fy = static_cast<float>(y);
  return {world::Explosion{{30, fy, 30}, 6, 1.2f}, world::Smooth{{33, fy - 2, 31}, 5, 0.5f},
          world::Brush{{20, fy + 1, 34}, 4, 0.7f, true, std::nullopt},
          world::Explosion{{12, fy, 12}, 5, 1}};
}

// A checkpointed chunk may be evicted like any other; read back, it is what it was, and
// edits go on from it exactly as on a world that never evicted it.
TEST(PipelineStore, CheckpointedChunksAreEvictedAndReadBackUnchanged) {
  const test::TempDir tmp("pstore_evict");
  const auto dir = tmp / "world";
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  auto cp = store::open_world_store(dir.string(), {.seed = 3, .record_start = false});
  WorldPipeline p(PipelineConfig{.seed = 3,
                                 .threads = 2,
                                 .evict_after = 500ms,
                                 .evict_min_age = 1ms,
                                 .store = store.get(),
                                 .checkpoint_store = cp.get(),
                                 .checkpoint = {.interval = 20ms}});
  WorldPipeline memory(PipelineConfig{.seed = 3, .threads = 2});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  const mesh::ChunkBox box{{-1, y / 32 - 1, -1}, {2, y / 32 + 1, 2}};
  p.load(box).get();
  memory.load(box).get();
  for (const world::Edit& e : border_edits(y)) {
    ASSERT_TRUE(p.submit(e).get().accepted);
    ASSERT_TRUE(memory.submit(e).get().accepted);
  }
  // Compared with `memory` (which evicts nothing for minutes): `p` may evict as soon as
  // 500 ms after a chunk was used, which a slow (sanitizer) build reaches mid-test.
  const auto before = samples_around(memory, 24, y, 24, 14);
  const world::ChunkCoord edited{0, y / 32, 0};
  const std::vector<uint8_t> mesh_before = memory.meshes().get(edited)->encoding;

  ASSERT_TRUE(eventually([&] {
    const PipelineStats s = p.stats();
    return s.unsaved_chunks == 0 && s.modified_chunks == 0;
  })) << "checkpointed chunks were not evicted";
  EXPECT_GT(p.stats().stored_chunks, 0u);
  EXPECT_EQ(store->info().logged_edits, 0u) << "the checkpoint did not trim the log";

  p.load(box).get();
  EXPECT_EQ(samples_around(p, 24, y, 24, 14), before);
  const MeshVersionPtr reloaded = p.meshes().get(edited);  // held: not evicted now
  ASSERT_TRUE(reloaded);
  EXPECT_EQ(reloaded->encoding, mesh_before);
  const world::Edit next = world::Smooth{{31, static_cast<float>(y), 32}, 6, 0.8f};
  ASSERT_TRUE(p.submit(next).get().accepted);
  ASSERT_TRUE(memory.submit(next).get().accepted);
  EXPECT_EQ(samples_around(p, 24, y, 24, 14), samples_around(memory, 24, y, 24, 14));
  p.stop();
}

// A level-of-detail chunk over modified chunks that were checkpointed and evicted reads
// them back from the store: it shows the edits, as a pipeline that kept them.
TEST(PipelineStore, ACoarseChunkOverEvictedModifiedChunksShowsTheirEdits) {
  const test::TempDir tmp("pstore_lod_evict");
  const auto dir = tmp / "world";
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{.seed = 3,
                                 .threads = 2,
                                 .evict_after = 300ms,
                                 .evict_min_age = 1ms,
                                 .store = store.get(),
                                 .checkpoint = {.interval = 20ms}});
  WorldPipeline memory(PipelineConfig{.seed = 3, .threads = 2});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  for (const world::Edit& e : border_edits(y)) {
    ASSERT_TRUE(p.submit(e).get().accepted);
    ASSERT_TRUE(memory.submit(e).get().accepted);
  }
  ASSERT_TRUE(eventually([&] { return p.stats().modified_chunks == 0; }))
      << "checkpointed chunks were not evicted";
  const LodKey key{{1, {0, world::floor_div(y, 64), 0}}, {}};
  p.set_lod_view(1, {key});
  memory.set_lod_view(1, {key});
  ASSERT_TRUE(eventually([&] { return p.lod_meshes().get(key) && memory.lod_meshes().get(key); }));
  EXPECT_EQ(p.lod_meshes().get(key)->encoding, memory.lod_meshes().get(key)->encoding);
  WorldPipeline plain(PipelineConfig{.seed = 3, .threads = 2});  // no edits
  plain.set_lod_view(1, {key});
  ASSERT_TRUE(eventually([&] { return plain.lod_meshes().get(key) != nullptr; }));
  EXPECT_NE(plain.lod_meshes().get(key)->encoding, p.lod_meshes().get(key)->encoding)
      << "the edits do not show at level 1";
  p.stop();
}

// A coarse chunk whose footprint holds more evicted modified chunks than one pass may read
// back (32) still gets its mesh: each pass reads some (it was put off for ever before).
TEST(PipelineStore, ACoarseChunkOverMoreEvictedChunksThanOnePassReadsIsStillMeshed) {
  const test::TempDir tmp("pstore_lod_many");
  const auto dir = tmp / "world";
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{.seed = 3,
                                 .threads = 2,
                                 .evict_after = 300ms,
                                 .evict_min_age = 1ms,
                                 .store = store.get(),
                                 .checkpoint = {.interval = 20ms}});
  WorldPipeline memory(PipelineConfig{.seed = 3, .threads = 2});
  const world::TerrainGenerator gen(3);
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j < 7; ++j) {  // 49 chunks, each with a dent
      const float x = 16.0f + 32.0f * i, z = 16.0f + 32.0f * j;
      const world::Edit e = world::Brush{
          {x, gen.height_at(static_cast<int>(x), static_cast<int>(z)), z}, 3, 1.0f, true};
      ASSERT_TRUE(p.submit(e).get().accepted);
      ASSERT_TRUE(memory.submit(e).get().accepted);
    }
  ASSERT_TRUE(eventually([&] { return p.stats().modified_chunks == 0; }))
      << "checkpointed chunks were not evicted";
  const LodKey key{{3, {0, world::floor_div(static_cast<int>(gen.height_at(100, 100)), 256), 0}},
                   {}};
  p.set_lod_view(1, {key});
  memory.set_lod_view(1, {key});
  ASSERT_TRUE(eventually([&] { return p.lod_meshes().get(key) && memory.lod_meshes().get(key); }))
      << "the coarse chunk was never meshed";
  EXPECT_EQ(p.lod_meshes().get(key)->encoding, memory.lod_meshes().get(key)->encoding);
  p.stop();
}

// A checkpoint the store refuses (here the last one, at stop) loses nothing: the log still
// has the edits, and the next start replays them and checkpoints them.
TEST(PipelineStore, ACheckpointTheStoreRefusedLosesNothing) {
  test::PostgresServer server;
  auto store = store::open_world_store(server.create_database("checkpoint"), {.seed = 3});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  const mesh::ChunkBox box{{-1, y / 32 - 1, -1}, {2, y / 32 + 1, 2}};
  const PipelineConfig config{
      .seed = 3, .threads = 2, .store = store.get(), .checkpoint = {.interval = 1h}};
  std::vector<world::Sample> before;
  {
    WorldPipeline p(config);
    p.load(box).get();
    for (const world::Edit& e : border_edits(y)) ASSERT_TRUE(p.submit(e).get().accepted);
    before = samples_around(p, 24, y, 24, 14);
    server.stop();
    p.stop();
    EXPECT_EQ(p.stats().checkpoint_failures, 1u);
    EXPECT_GT(p.stats().unsaved_chunks, 0u);
  }
  server.start();
  WorldPipeline p(config);
  p.load(box).get();
  EXPECT_EQ(samples_around(p, 24, y, 24, 14), before);
  p.stop();
  EXPECT_EQ(p.stats().checkpoints, 1u);
  const store::WorldInfo info = store->info();
  EXPECT_EQ(info.checkpoint_seq, border_edits(y).size());
  EXPECT_EQ(info.logged_edits, 0u);
}

// Edits that changed no chunk (an explosion in the air) are in the log all the same; a
// checkpoint trims them, or a client could grow the log (and the replay) without end.
TEST(PipelineStore, EditsThatChangedNothingAreTrimmedFromTheLog) {
  const test::TempDir tmp("pstore_noop");
  const auto dir = tmp / "world";
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  {
    WorldPipeline p(PipelineConfig{
        .seed = 3, .threads = 2, .store = store.get(), .checkpoint = {.interval = 1h}});
    for (int i = 0; i < 20; ++i) {
      const auto r = p.submit(world::Explosion{{30, float(y + 300), 30}, 6, 1}).get();
      ASSERT_TRUE(r.accepted) << r.message;
    }
    p.stop();  // the final checkpoint
  }
  const store::WorldInfo info = store->info();
  EXPECT_EQ(info.checkpoint_seq, 20u);
  EXPECT_EQ(info.logged_edits, 0u);
}

void run_sql(const std::filesystem::path& dir, const char* query) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "world.sqlite").c_str(), &db), SQLITE_OK);
  sqlite3_busy_timeout(db, 5000);
  char* error = nullptr;
  EXPECT_EQ(sqlite3_exec(db, query, nullptr, nullptr, &error), SQLITE_OK) << (error ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

// A world of seed 3 with one explosion at (30, surface, 30), checkpointed (the pipeline
// stopped); returns the surface height there.
int checkpointed_explosion(const std::filesystem::path& dir) {
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = store.get()});
  EXPECT_TRUE(p.submit(world::Explosion{{30, float(y), 30}, 6, 1.2f}).get().accepted);
  return y;
}

// A stored chunk the store cannot give back for a while: the view load waiting for it is
// tried again by itself once the store works (not only when something else wakes the
// pipeline).
TEST(PipelineStore, ALoadWaitingForAnUnreadableStoredChunkIsRetriedByItself) {
  const test::TempDir tmp("pstore_unreadable");
  const auto dir = tmp / "world";
  const int y = checkpointed_explosion(dir);
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{
      .seed = 3, .threads = 2, .store = store.get(), .store_retry = std::chrono::milliseconds(50)});
  run_sql(dir, "ALTER TABLE chunks RENAME TO chunks_away");
  auto loaded = p.load(mesh::ChunkBox{{0, y / 32, 0}, {0, y / 32, 0}});
  EXPECT_EQ(loaded.wait_for(300ms), std::future_status::timeout);
  run_sql(dir, "ALTER TABLE chunks_away RENAME TO chunks");
  EXPECT_EQ(loaded.wait_for(10s),
            std::future_status::ready);  // retried every 50 ms; slack for TSan
  p.stop();
}

// A damaged checkpointed chunk: an edit that needs it is refused, saying so (not "disk
// full"), and the world is not touched; the server goes on.
TEST(PipelineStore, AnEditNeedingADamagedStoredChunkIsRefusedSayingSo) {
  const test::TempDir tmp("pstore_damaged");
  const auto dir = tmp / "world";
  const int y = checkpointed_explosion(dir);
  run_sql(dir, "UPDATE chunks SET samples = x'0102'");
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = store.get()});
  const EditResult r = p.submit(world::Brush{{30, float(y), 30}, 3}).get();
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.reason, world::RefusalReason::kStorageUnavailable);
  EXPECT_NE(r.message.find("cannot be read from the world store"), std::string::npos) << r.message;
  // Elsewhere the world goes on.
  EXPECT_TRUE(p.submit(world::Explosion{{900, float(y), 900}, 3, 1}).get().accepted);
  p.stop();
}

// Edits keep coming while the writer encodes a checkpoint; they change chunks it has not
// reached yet. Every checkpoint must hold its chunks as of its own sequence number: each
// is read back the moment it landed and compared with a world that applied exactly the
// edits up to that number.
TEST(PipelineStore, EditsWhileACheckpointIsWrittenDoNotReachIt) {
  const test::TempDir tmp("pstore_cow");
  const auto dir = tmp / "world";
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  auto cp = store::open_world_store(dir.string(), {.seed = 3, .record_start = false});
  using Snapshot = std::map<world::ChunkCoord, world::Chunk>;
  std::vector<std::pair<uint64_t, Snapshot>> landed;  // pipeline thread, then read after stop
  PipelineObserver observer{.checkpoint = [&](double, size_t, size_t, bool ok) {
    if (!ok) return;
    auto reader = store::open_world_store(dir.string(), {.read_only = true});
    Snapshot chunks;
    reader->for_each_chunk([&](world::ChunkCoord c, uint64_t) {
      chunks.emplace(c, *store::decode_chunk(reader->read_chunk(c)->samples));
    });
    landed.emplace_back(reader->info().checkpoint_seq, std::move(chunks));
  }};
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(30, 30));
  std::vector<world::Edit> edits;
  for (int i = 0; i < 48; ++i) {
    const world::Vec3 at{static_cast<float>(8 + (i * 7) % 48), static_cast<float>(y),
                         static_cast<float>(8 + (i * 11) % 48)};
    if (i % 4 == 3) {
      edits.push_back(world::Smooth{at, 4, 0.6f});
    } else {
      edits.push_back(world::Explosion{at, 4, 0.8f});
    }
  }
  {
    WorldPipeline p(PipelineConfig{.seed = 3,
                                   .threads = 2,
                                   .store = store.get(),
                                   .checkpoint_store = cp.get(),
                                   .checkpoint = {.interval = 1h, .max_unsaved_chunks = 4}},
                    observer);
    // Waves of 6 queued at once (their batches overlap the writer), each answered before
    // the next: however the batches fall, several checkpoints start between the waves.
    for (size_t from = 0; from < edits.size(); from += 6) {
      std::vector<std::future<EditResult>> results;
      for (size_t i = from; i < std::min(edits.size(), from + 6); ++i)
        results.push_back(p.submit(edits[i]));
      for (auto& r : results) ASSERT_TRUE(r.get().accepted);
    }
    p.stop();
  }
  ASSERT_GE(landed.size(), 2u) << "too few checkpoints to prove anything";
  for (const auto& entry : landed) {  // not a structured binding: clang 14 cannot capture one
    const uint64_t seq = entry.first;
    const Snapshot& chunks = entry.second;
    WorldPipeline memory(PipelineConfig{.seed = 3, .threads = 2});
    for (uint64_t i = 0; i < seq; ++i) ASSERT_TRUE(memory.submit(edits[i]).get().accepted);
    size_t differ = 0;
    memory.inspect([&](const world::ChunkMap& map) {
      for (const auto& [c, chunk] : chunks) {
        const world::Chunk* expected = map.find(c);
        differ += expected && *expected == chunk ? 0 : 1;
      }
    });
    EXPECT_EQ(differ, 0u) << "the checkpoint through edit " << seq << " holds later changes";
  }
}

}  // namespace
}  // namespace vox::pipeline
