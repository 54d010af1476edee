// Pipelined group commit: while a batch's append is in flight the pipeline applies the
// next batches, yet nothing of a batch is published and no edit of it answered before its
// append is durable; answers keep batch order; an append that fails undoes its batch and
// every batch applied on top of it. The stores are real (SQLite, a PostgreSQL server the
// test starts); a gate in front of append_edits holds an append in flight.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <condition_variable>
#include <filesystem>
#include <future>
#include <mutex>
#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_sampler.hpp"
#include "tests/gated_store.hpp"
#include "tests/lod_test_util.hpp"
#include "tests/pipeline_test_util.hpp"
#include "tests/postgres_server.hpp"
#include "tests/temp_dir.hpp"

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;

using test::eventually;
using test::GatedStore;
using test::samples_around;

std::vector<uint64_t> logged_seqs(store::WorldStore& s) {
  std::vector<uint64_t> seqs;
  s.for_each_edit(0, [&](const store::LoggedEdit& e) {
    seqs.push_back(e.seq);
    return true;
  });
  return seqs;
}

// The appender's thread lands appends in order, runs those still queued before it ends,
// and does not try one queued behind a failed one.
TEST(StoreAppender, AppendsLandInOrderAndNoneIsDroppedAtTheEnd) {
  const test::TempDir tmp("pcommit_appender");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  std::atomic<int> landed{0};
  std::shared_future<AppendOutcome> first, second;
  {
    StoreAppender appender(store, [&] { ++landed; });
    store.close();
    const world::Edit e = world::Explosion{{1, 2, 3}, 4, 1};
    first = appender.append({{1, 0, "", e}}, {}, {});
    ASSERT_TRUE(store.wait_entered(1));
    second = appender.append({{2, 0, "", e}}, {}, first);
    store.open();
  }
  EXPECT_EQ(first.get().error, "");
  EXPECT_EQ(second.get().error, "");
  EXPECT_EQ(landed, 2);
  EXPECT_EQ(logged_seqs(*sqlite), (std::vector<uint64_t>{1, 2}));
  std::promise<AppendOutcome> failed;
  failed.set_value({.error = "disk full"});
  StoreAppender appender(store, nullptr);
  EXPECT_EQ(
      appender
          .append({{3, 0, "", world::Explosion{{1, 2, 3}, 4, 1}}}, {}, failed.get_future().share())
          .get()
          .error,
      "not tried: an earlier append failed");
  EXPECT_EQ(logged_seqs(*sqlite).size(), 2u);
}

// A real SQLite world behind a gate, for the appender's grouping tests.
struct GatedWorld {
  explicit GatedWorld(const std::string& tag)
      : tmp("pcommit_" + tag),
        dir(tmp / "world"),
        sqlite(store::open_world_store(dir.string(), {.seed = 3})),
        store(*sqlite) {}
  // An edit to log as sequence number `seq`.
  static store::LoggedEdit edit(uint64_t seq) {
    return {seq, 0, "", world::Explosion{{1, 2, 3}, 4, 1}};
  }
  // Appends edit 1 alone and holds it at the closed gate: what is appended next queues.
  std::shared_future<AppendOutcome> hold_first(StoreAppender& appender) {
    store.close();
    auto first = appender.append({edit(1)}, {}, {});
    EXPECT_TRUE(store.wait_entered(1));
    return first;
  }

  test::TempDir tmp;  // first: removed after the store closed
  std::filesystem::path dir;
  std::unique_ptr<store::WorldStore> sqlite;
  GatedStore store;
};

// Group commit across batches: the appends queued behind one being made durable go to the
// store in one transaction (one fsync) and each learns it; one carrying regions goes alone.
TEST(StoreAppender, AppendsQueuedBehindASlowOneGoInOneTransaction) {
  GatedWorld w("group");
  std::vector<std::shared_future<AppendOutcome>> out;
  {
    StoreAppender appender(w.store, nullptr);
    out.push_back(w.hold_first(appender));
    out.push_back(appender.append({w.edit(2), w.edit(3)}, {}, out.back()));
    out.push_back(appender.append({w.edit(4)}, {}, out.back()));
    store::RegionWrite regions;
    regions.next_id = 1;
    out.push_back(appender.append({w.edit(5)}, {}, out.back(), regions));
    out.push_back(appender.append({w.edit(6)}, {}, out.back()));
    w.store.open();
  }
  EXPECT_EQ(w.store.entered(), 4);  // {1}, {2, 3, 4}, {5} with regions, {6}
  const std::vector<size_t> edits{1, 3, 3, 1, 1};
  const std::vector<bool> first{true, true, false, true, true};
  for (size_t i = 0; i < out.size(); ++i) {
    const AppendOutcome& o = out[i].get();
    EXPECT_EQ(o.error, "") << i;
    EXPECT_EQ(o.edits, edits[i]) << i;
    EXPECT_EQ(o.first, first[i]) << i;
  }
  EXPECT_EQ(logged_seqs(*w.sqlite), (std::vector<uint64_t>{1, 2, 3, 4, 5, 6}));
}

// A transaction carrying several appends fails for all of them (none of their edits is
// logged), and a group queued behind it is not tried.
TEST(StoreAppender, AGroupedTransactionThatFailsFailsEveryAppendInItAndTheOnesBehind) {
  GatedWorld w("group_fail");
  std::vector<std::shared_future<AppendOutcome>> out;
  {
    StoreAppender appender(w.store, nullptr);
    out.push_back(w.hold_first(appender));
    out.push_back(appender.append({w.edit(2)}, {}, out.back()));
    out.push_back(appender.append({w.edit(3)}, {}, out.back()));
    w.store.set_failing_from(2);  // the first append lands, the group {2, 3} fails
    w.store.open();
    out[2].wait();
    out.push_back(appender.append({w.edit(4)}, {}, out.back()));
  }
  EXPECT_EQ(w.store.entered(), 2);  // {1}, {2, 3}; {4} not tried
  EXPECT_EQ(out[0].get().error, "");
  for (size_t i = 1; i < 3; ++i) EXPECT_EQ(out[i].get().error, "test: the disk is full") << i;
  EXPECT_EQ(out[3].get().error, "not tried: an earlier append failed");
  EXPECT_EQ(logged_seqs(*w.sqlite), (std::vector<uint64_t>{1}));
}

// The commit part alone (server/pipeline/durable_commit.hpp), with no pipeline around it:
// batches numbered in order, answered oldest first once durable, never before.
struct CommitLog {
  std::vector<std::pair<int, bool>> answered;  // batch tag, durable
  std::vector<int> undone;
  int committed = 0;
  DurableCommit::Hooks hooks() {
    return {
        .answer = [this](EditBatch& b, bool durable) { answered.emplace_back(tag(b), durable); },
        .undo = [this](EditBatch& b) { undone.push_back(tag(b)); },
        .committed = [this](const AppendOutcome&, double) { ++committed; }};
  }
  static int tag(const EditBatch& b) { return static_cast<int>(b.results.size()); }
};

// A batch of `edits` accepted edits, tagged by its number of results.
EditBatch batch_of(int tag, std::vector<EditTask>& tasks, size_t edits) {
  EditBatch b;
  b.results.resize(static_cast<size_t>(tag));
  for (size_t i = 0; i < edits; ++i) {
    b.accepted.push_back(&tasks.at(i));
    b.keep.emplace_back();
  }
  return b;
}

TEST(DurableCommit, BatchesAreNumberedInOrderAndAnsweredOnlyOnceDurable) {
  GatedWorld w("commit_order");
  std::vector<EditTask> tasks(3);
  for (EditTask& t : tasks) t.edit = world::Explosion{{1, 2, 3}, 4, 1};
  CommitLog log;
  std::atomic<int> landed{0};
  {
    DurableCommit commit(
        w.store, std::chrono::milliseconds(100), [&] { ++landed; }, log.hooks());
    commit.restore(10);
    w.store.close();
    for (int tag = 1; tag <= 2; ++tag) {
      EditBatch b = batch_of(tag, tasks, tag == 1 ? 1 : 3);
      commit.start(b, std::nullopt);
      commit.add(std::move(b));
    }
    EXPECT_EQ(commit.size(), 2u);
    EXPECT_EQ(commit.edits_in_flight(), 4u);
    EXPECT_EQ(commit.last_seq(), 13u);
    ASSERT_TRUE(w.store.wait_entered(1));
    commit.finish(SIZE_MAX);  // nothing landed: nothing answered, nothing waited for
    EXPECT_TRUE(log.answered.empty());
    EXPECT_FALSE(commit.oldest_landed());
    w.store.open();
    commit.finish(0);  // waits for both
    EXPECT_TRUE(commit.empty());
  }
  EXPECT_EQ(log.answered, (std::vector<std::pair<int, bool>>{{1, true}, {2, true}}));
  EXPECT_TRUE(log.undone.empty());
  EXPECT_GE(landed.load(), 1);
  EXPECT_EQ(logged_seqs(*w.sqlite), (std::vector<uint64_t>{10, 11, 12, 13}));
}

TEST(DurableCommit, AFailedAppendUndoesEveryPendingBatchNewestFirstAndTheStoreRests) {
  GatedWorld w("commit_fail");
  std::vector<EditTask> tasks(2);
  for (EditTask& t : tasks) t.edit = world::Explosion{{1, 2, 3}, 4, 1};
  CommitLog log;
  DurableCommit commit(w.store, std::chrono::seconds(60), nullptr, log.hooks());
  w.store.set_failing(true);
  w.store.close();
  for (int tag = 1; tag <= 3; ++tag) {
    EditBatch b = batch_of(tag, tasks, 2);
    commit.start(b, std::nullopt);
    commit.add(std::move(b));
  }
  ASSERT_TRUE(w.store.wait_entered(1));
  w.store.open();
  const auto before = Clock::now();
  commit.finish(0);
  EXPECT_TRUE(commit.empty());
  EXPECT_EQ(log.undone, (std::vector<int>{3, 2, 1}));  // newest first, before any answer
  EXPECT_EQ(log.answered, (std::vector<std::pair<int, bool>>{{1, false}, {2, false}, {3, false}}));
  EXPECT_TRUE(commit.resting(before + std::chrono::seconds(59)));
  EXPECT_TRUE(logged_seqs(*w.sqlite).empty());
  // The next append that works forgets the failed ones' numbers (they may have landed)
  // and never gives them again.
  w.store.set_failing(false);
  EditBatch next = batch_of(4, tasks, 1);
  commit.start(next, std::nullopt);
  commit.add(std::move(next));
  commit.finish(0);
  EXPECT_EQ(logged_seqs(*w.sqlite), (std::vector<uint64_t>{7}));
  EXPECT_EQ(log.answered.back(), (std::pair<int, bool>{4, true}));
}

TEST(PipelinedCommit, TheNextBatchAppliesWhileAnAppendIsInFlightAndAnswersKeepTheirOrder) {
  const test::TempDir tmp("pcommit_order");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = &store});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {2, y / 32 + 1, 2}}).get();
  const uint64_t published = p.stats().meshes_published;
  const auto far_before = samples_around(p, 50, y, 50, 3);

  store.close();
  std::mutex order_mutex;
  std::vector<int> order;
  std::promise<EditResult> first, second;
  p.submit(world::Explosion{{10, float(y), 10}, 4, 1}, [&](const EditResult& r) {
    std::lock_guard lock(order_mutex);
    order.push_back(1);
    first.set_value(r);
  });
  ASSERT_TRUE(store.wait_entered(1));
  p.submit(world::Explosion{{50, float(y), 50}, 4, 1}, [&](const EditResult& r) {
    std::lock_guard lock(order_mutex);
    order.push_back(2);
    second.set_value(r);
  });
  // The second batch applied while the first append is held (an inspection after it sees
  // its samples), but neither is answered nor published.
  EXPECT_NE(samples_around(p, 50, y, 50, 3), far_before) << "the next batch did not apply";
  auto first_result = first.get_future();
  auto second_result = second.get_future();
  EXPECT_EQ(first_result.wait_for(50ms), std::future_status::timeout);
  EXPECT_EQ(second_result.wait_for(0ms), std::future_status::timeout);
  EXPECT_EQ(p.stats().meshes_published, published) << "a mesh was published before its append";
  EXPECT_TRUE(logged_seqs(*sqlite).empty());

  store.open();
  ASSERT_TRUE(first_result.get().accepted);
  ASSERT_TRUE(second_result.get().accepted);
  EXPECT_EQ(order, (std::vector<int>{1, 2}));
  EXPECT_GT(p.stats().meshes_published, published);
  EXPECT_EQ(logged_seqs(*sqlite).size(), 2u);
  p.stop();
}

TEST(PipelinedCommit, ALoadBesideAnEditInFlightPublishesOnlyOnceTheEditIsDurable) {
  const test::TempDir tmp("pcommit_load");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = &store});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  const world::ChunkCoord at{0, y / 32, 0};
  store.close();
  // Nothing is meshed there yet: the edit generates the chunk it touches and re-meshes
  // nothing; a load of its neighbourhood right after must not show it before it is durable.
  auto edit = p.submit(world::Explosion{{10, float(y), 10}, 6, 1});
  ASSERT_TRUE(store.wait_entered(1));
  auto load = p.load(mesh::ChunkBox{at.offset(-1, -1, -1), at.offset(1, 1, 1)});
  EXPECT_EQ(load.wait_for(200ms), std::future_status::timeout)
      << "a load published meshes showing an edit whose append had not landed";
  EXPECT_EQ(p.stats().meshes_published, 0u);
  store.open();
  ASSERT_TRUE(edit.get().accepted);
  ASSERT_EQ(load.wait_for(10s), std::future_status::ready);
  p.stop();
}

// A LOD mesh never shows an edit that is not durable; but while any batch waited for the
// store, no LOD mesh was made at all, and 200 players' first views (edits arriving at 100
// a second) waited 6 s instead of 3. Now only the meshes reading a chunk the pending edit
// changed wait: one far from it is meshed while the append is held, one over it only
// once the append has landed, and it shows the edit.
TEST(PipelinedCommit, OnlyTheCoarseMeshesOverAnEditInFlightWaitForItsAppend) {
  const test::TempDir tmp("pcommit_lod");
  auto sqlite = store::open_world_store((tmp / "world").string(), {.seed = 3});
  GatedStore store(*sqlite);
  std::mutex mutex;
  std::vector<LodKey> seen;
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = &store});
  p.subscribe_lod([&](const WorldPipeline::LodPublication& pub) {
    std::lock_guard lock(mutex);
    seen.insert(seen.end(), pub.keys.begin(), pub.keys.end());
  });
  const auto published = [&](const LodKey& k) {
    std::lock_guard lock(mutex);
    return std::find(seen.begin(), seen.end(), k) != seen.end();
  };
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  // Level-1 chunks (64 voxels) through the surface: one over the edit, one 640 voxels off.
  const LodKey over{{1, {0, world::floor_div(y, 64), 0}}, {}};
  const LodKey far{
      {1,
       {10, world::floor_div(static_cast<int>(world::TerrainGenerator(3).height_at(650, 10)), 64),
        0}},
      {}};
  store.close();
  auto edit = p.submit(world::Explosion{{10, float(y), 10}, 6, 1});
  ASSERT_TRUE(store.wait_entered(1));
  p.set_lod_view(1, {over, far});
  EXPECT_TRUE(eventually([&] { return published(far); }, 10s))
      << "a coarse mesh far from the edit waited for its append";
  EXPECT_FALSE(published(over)) << "a coarse mesh showed an edit whose append had not landed";
  store.open();
  ASSERT_TRUE(edit.get().accepted);
  ASSERT_TRUE(eventually([&] { return published(over); }, 10s));
  // Shows the edit: not the mesh of the terrain as generated.
  const world::TerrainGenerator generator(3);
  const world::TerrainSampler terrain(generator);
  ASSERT_NE(p.lod_meshes().get(over), nullptr);
  EXPECT_NE(p.lod_meshes().get(over)->encoding, test::direct_lod_encoding(terrain, over));
  p.stop();
}

TEST(PipelinedCommit, AFailedAppendUndoesTheBatchesAppliedOnTopOfIt) {
  test::PostgresServer server;
  auto pg = store::open_world_store(server.create_database("pipelined"), {.seed = 3});
  GatedStore store(*pg);
  WorldPipeline p(PipelineConfig{
      .seed = 3, .threads = 2, .store = &store, .store_retry = std::chrono::milliseconds(50)});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {1, y / 32 + 1, 1}}).get();
  const auto before = samples_around(p, 20, y, 20, 14);
  const uint64_t published = p.stats().meshes_published;

  store.close();
  auto a = p.submit(world::Explosion{{10, float(y), 10}, 5, 1});
  ASSERT_TRUE(store.wait_entered(1));
  auto b = p.submit(world::Explosion{{12, float(y), 12}, 5, 1});  // on top of a
  auto c = p.submit(world::Brush{{30, float(y), 30}, 4, 0.8f, true, std::nullopt});
  EXPECT_NE(samples_around(p, 20, y, 20, 14), before);  // applied, not durable yet
  server.stop();  // a's append now fails for real; b's and c's are not tried
  store.open();
  for (auto* f : {&a, &b, &c}) {
    const EditResult r = f->get();
    EXPECT_FALSE(r.accepted);
    EXPECT_EQ(r.reason, world::RefusalReason::kStorageUnavailable);
    EXPECT_TRUE(r.changed_chunks.empty());
  }
  EXPECT_EQ(samples_around(p, 20, y, 20, 14), before) << "an undone batch left samples behind";
  EXPECT_EQ(p.stats().meshes_published, published);

  server.start();
  std::this_thread::sleep_for(60ms);  // past store_retry
  const EditResult again = p.submit(world::Explosion{{12, float(y), 12}, 5, 1}).get();
  EXPECT_TRUE(again.accepted) << again.message;
  EXPECT_EQ(logged_seqs(*pg).size(), 1u) << "a refused edit is in the log";
  p.stop();
}

// A checkpoint fails while a batch on its chunks waits for its append, and then that
// append fails too. Undoing the batch put back its chunks' flags from before it, when the
// checkpoint held them ("saved"): the failed checkpoint's chunks were then never written,
// and the final checkpoint trimmed their edits from the log.
TEST(PipelinedCommit, AFailedCheckpointsChunksStayUnsavedWhenABatchOnThemIsUndone) {
  test::PostgresServer server;
  const std::string uri = server.create_database("checkpoint_then_append");
  auto pg = store::open_world_store(uri, {.seed = 3});
  auto pg_checkpoints = store::open_world_store(uri, {.seed = 3, .record_start = false});
  GatedStore appends(*pg);
  GatedStore checkpoints(*pg_checkpoints, /*gate_checkpoints=*/true);
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  const world::Edit kept = world::Explosion{{10, float(y), 10}, 4, 1};
  std::vector<world::Sample> expected;
  {
    WorldPipeline memory(PipelineConfig{.seed = 3, .threads = 2});
    memory.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {1, y / 32 + 1, 1}}).get();
    ASSERT_TRUE(memory.submit(kept).get().accepted);
    expected = samples_around(memory, 10, y, 10, 6);
  }
  {
    WorldPipeline p(PipelineConfig{.seed = 3,
                                   .threads = 2,
                                   .store = &appends,
                                   .checkpoint_store = &checkpoints,
                                   .checkpoint = {.interval = 1h,
                                                  .max_unsaved_chunks = 1,
                                                  .retry = std::chrono::milliseconds(50)},
                                   .store_retry = std::chrono::milliseconds(50)});
    p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {0, y / 32 + 1, 0}}).get();
    checkpoints.close();
    ASSERT_TRUE(p.submit(kept).get().accepted);
    ASSERT_TRUE(checkpoints.wait_entered(1));  // its chunks' checkpoint, held
    appends.close();
    auto undone = p.submit(world::Explosion{{12, float(y), 10}, 4, 1});
    ASSERT_TRUE(appends.wait_entered(2));  // on the same chunks, its append held
    server.stop();
    checkpoints.open();  // the checkpoint fails
    eventually([&] { return p.stats().checkpoint_failures > 0; }, 1s);
    appends.open();  // the append fails: the batch is undone
    EXPECT_EQ(undone.get().reason, world::RefusalReason::kStorageUnavailable);
    eventually([&] { return p.stats().checkpoint_failures > 0; }, 5s);
    EXPECT_GT(p.stats().unsaved_chunks, 0u) << "no checkpoint would write the kept edit's chunks";
    server.start();
    p.stop();  // the final checkpoint
  }
  auto reopened = store::open_world_store(uri, {.seed = 3});
  WorldPipeline q(PipelineConfig{.seed = 3, .threads = 2, .store = reopened.get()});
  q.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {1, y / 32 + 1, 1}}).get();
  EXPECT_EQ(samples_around(q, 10, y, 10, 6), expected) << "an accepted edit was lost";
}

// A failed append undoes the batches applied on top of it, newest first, also where they
// overlap. The pipeline once took a failure between applying a batch and holding it as
// pending: the failed batch was undone under it, then the later batch's own undo put the
// refused edit back into the world.
TEST(PipelinedCommit, AFailedAppendUnderAnOverlappingBatchLeavesTheWorldAsItWas) {
  const test::TempDir tmp("pcommit_overlap");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{
      .seed = 3, .threads = 2, .store = &store, .store_retry = std::chrono::milliseconds(20)});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {1, y / 32 + 1, 1}}).get();
  const auto before = samples_around(p, 10, y, 10, 8);
  for (int round = 0; round < 8; ++round) {
    store.close();
    store.set_failing(true);
    const int entered = store.entered();
    auto first = p.submit(world::Explosion{{10, float(y), 10}, 5, 1});
    ASSERT_TRUE(store.wait_entered(entered + 1));
    auto second = p.submit(world::Explosion{{12, float(y) + 1, 11}, 5, 1});
    std::this_thread::sleep_for(std::chrono::microseconds(250 * round));
    store.open();
    EXPECT_EQ(first.get().reason, world::RefusalReason::kStorageUnavailable);
    EXPECT_EQ(second.get().reason, world::RefusalReason::kStorageUnavailable);
    EXPECT_EQ(samples_around(p, 10, y, 10, 8), before) << "a refused edit stayed, round " << round;
    store.set_failing(false);
    std::this_thread::sleep_for(std::chrono::milliseconds(30));  // the store's rest
  }
  EXPECT_TRUE(p.submit(world::Explosion{{10, float(y), 10}, 5, 1}).get().accepted);
  p.stop();
}

// A flood of 7,000 edits/s outran the checkpoints and grew the log to 80,791 edits, which
// a restart replayed for 8.9 s: past its bound, the log takes no more edits (SERVER_BUSY)
// until the checkpoint in progress trims it.
TEST(PipelinedCommit, EditsAreHeldBackWhileTheLogTailIsAtItsBound) {
  const test::TempDir tmp("pcommit_tail");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  auto second = store::open_world_store(dir.string(), {.seed = 3, .record_start = false});
  GatedStore checkpoints(*second, /*gate_checkpoints=*/true);
  WorldPipeline p(
      PipelineConfig{.seed = 3,
                     .threads = 2,
                     .store = sqlite.get(),
                     .checkpoint_store = &checkpoints,
                     .checkpoint = {.interval = 1h, .max_unsaved_edits = 4, .max_log_tail = 6}});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {0, y / 32 + 1, 0}}).get();
  checkpoints.close();
  int x = 0;
  auto explode = [&] { return p.submit(world::Explosion{{float(x++), float(y), 10}, 3, 1}).get(); };
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(explode().accepted);
  ASSERT_TRUE(checkpoints.wait_entered(1));  // the checkpoint of those four, held
  for (int i = 0; i < 2; ++i) ASSERT_TRUE(explode().accepted);
  const EditResult held = explode();
  EXPECT_EQ(held.reason, world::RefusalReason::kServerBusy) << held.message;
  EXPECT_EQ(logged_seqs(*sqlite).size(), 6u);
  checkpoints.open();
  eventually([&] { return p.stats().checkpoints > 0; }, 5s);
  EXPECT_TRUE(explode().accepted) << "the log stayed full after the checkpoint";
  p.stop();
}

// A region change whose append failed yet landed (the connection dropped at COMMIT) was
// answered STORAGE_UNAVAILABLE: once the store works, the pipeline writes the regions as
// they are by itself, with no edit to carry it, so a restart does not bring it back.
TEST(PipelinedCommit, ARegionChangeInDoubtIsWrittenBackByItselfOnceTheStoreWorks) {
  const test::TempDir tmp("pcommit_region_doubt");
  const auto dir = tmp / "world";
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{.seed = 3,
                                 .threads = 2,
                                 .store = &store,
                                 .checkpoint = {.interval = std::chrono::hours(1)},
                                 .store_retry = 50ms});
  // Read on a connection of the test's own (the pipeline's is used on its threads).
  auto reader = store::open_world_store(dir.string(), {.read_only = true});
  world::Region r;
  r.box = {{0, 0, 0}, {9, 9, 9}};
  std::promise<RegionOutcome> done;
  store.set_fail_after_write(true);
  p.change_regions(RegionTask{r, 0, "admin", [&](const RegionOutcome& o) { done.set_value(o); }});
  EXPECT_EQ(done.get_future().get().status, RegionOutcome::Status::kStorageUnavailable);
  EXPECT_EQ(reader->read_regions().regions.size(), 1u) << "the test's append did not land";
  EXPECT_TRUE(p.regions()->empty());
  store.set_fail_after_write(false);
  EXPECT_TRUE(eventually([&] { return reader->read_regions().regions.empty(); }))
      << "the region refused stayed in the store";
  const uint64_t next = reader->read_regions().next_id;
  EXPECT_GE(next, 2u) << "its id is not given again";
  std::promise<RegionOutcome> again;
  p.change_regions(RegionTask{r, 0, "admin", [&](const RegionOutcome& o) { again.set_value(o); }});
  const RegionOutcome added = again.get_future().get();
  ASSERT_EQ(added.status, RegionOutcome::Status::kOk);
  EXPECT_GE(added.region.id, 2u);
  p.stop();
}

}  // namespace
}  // namespace vox::pipeline
