// The world pipeline's parts, each on its own, with no pipeline around it: the protected
// regions' table (server/pipeline/protected_regions.hpp), the stored-chunk reader
// (stored_chunk_reader.hpp), the checkpoints (checkpoints.hpp), the view loads
// (view_loads.hpp), the memory keeper (memory_keeper.hpp), the inbox (inbox.hpp) and the
// subscribers (subscribers.hpp).
#include <gtest/gtest.h>

#include <map>
#include <stdexcept>
#include <thread>

#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/inbox.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/subscribers.hpp"
#include "server/pipeline/view_loads.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"
#include "tests/chunk_store_stub.hpp"

namespace vox::pipeline {
namespace {

world::Region region(int32_t x, std::string name) {
  world::Region r;
  r.box = {{x, 0, 0}, {x + 8, 8, 8}};
  r.name = std::move(name);
  r.owners = {"alice"};
  return r;
}

RegionTask add(world::Region r) { return RegionTask{.add = std::move(r)}; }
RegionTask remove(uint64_t id) { return RegionTask{.remove_id = id}; }

TEST(ProtectedRegions, ChangesAreInForceAtOnceAndPublishedOnlyOnceDurable) {
  ProtectedRegions regions({});
  regions.restore({.regions = {}, .next_id = 5});
  RegionChanges batch;
  regions.apply(add(region(0, "spawn")), 0, false, batch, "resting");
  regions.apply(add(region(100, "castle")), 1, false, batch, "resting");
  regions.seal(batch);
  ASSERT_EQ(batch.outcomes.size(), 2u);
  EXPECT_EQ(batch.outcomes[0].second.region.id, 5u);  // ids go on from the store's
  EXPECT_EQ(batch.outcomes[1].second.region.id, 6u);
  EXPECT_EQ(regions.in_force().size(), 2u);   // edits of this batch are clipped by them
  EXPECT_TRUE(regions.published()->empty());  // readers wait for the store
  const auto write = regions.write_for_append(batch);
  ASSERT_TRUE(write.has_value());
  EXPECT_FALSE(write->whole);
  EXPECT_EQ(write->upsert.size(), 2u);
  EXPECT_EQ(write->next_id, 7u);
  EXPECT_TRUE(batch.carried);
  regions.landed(batch);
  EXPECT_EQ(regions.published()->size(), 2u);

  RegionChanges removal;
  regions.apply(remove(5), 0, false, removal, "resting");
  regions.seal(removal);
  EXPECT_EQ(regions.in_force().size(), 1u);
  EXPECT_EQ(regions.write_for_append(removal)->remove, std::vector<uint64_t>{5});
  regions.landed(removal);
  ASSERT_EQ(regions.published()->size(), 1u);
  EXPECT_EQ(regions.published()->front().name, "castle");
}

TEST(ProtectedRegions, AFailedAppendRestoresTheTableAndTheNextAppendWritesItWhole) {
  ProtectedRegions regions({});
  RegionChanges first;
  regions.apply(add(region(0, "a")), 0, false, first, "resting");
  regions.seal(first);
  regions.write_for_append(first);
  regions.landed(first);
  RegionChanges second;
  regions.apply(add(region(50, "b")), 0, false, second, "resting");
  regions.seal(second);
  regions.write_for_append(second);
  regions.undo(second);  // the append failed: it may have landed or not
  EXPECT_EQ(regions.in_force().size(), 1u);
  EXPECT_EQ(regions.published()->size(), 1u);
  EXPECT_TRUE(regions.doubtful());
  RegionChanges repair;  // no tasks: the table alone
  const auto write = regions.write_for_append(repair);
  ASSERT_TRUE(write.has_value());
  EXPECT_TRUE(write->whole);
  ASSERT_EQ(write->upsert.size(), 1u);
  EXPECT_EQ(write->upsert[0].name, "a");
  EXPECT_EQ(write->next_id, 3u);  // the undone id is never given again
  regions.landed(repair);
  EXPECT_FALSE(regions.doubtful());
  RegionChanges third;
  regions.apply(add(region(50, "c")), 0, false, third, "resting");
  EXPECT_EQ(third.outcomes[0].second.region.id, 3u);
}

TEST(ProtectedRegions, RefusalsSayWhyAndChangeNothing) {
  using Status = RegionOutcome::Status;
  ProtectedRegions regions({});
  RegionChanges batch;
  regions.apply(add(region(0, "a")), 0, true, batch, "the store rests");
  regions.apply(remove(42), 1, false, batch, "the store rests");
  world::Region empty_box = region(0, "bad");
  empty_box.box.hi = {-1, -1, -1};
  regions.apply(add(empty_box), 2, false, batch, "the store rests");
  ASSERT_EQ(batch.outcomes.size(), 3u);
  EXPECT_EQ(batch.outcomes[0].second.status, Status::kStorageUnavailable);
  EXPECT_EQ(batch.outcomes[0].second.message, "the store rests");
  EXPECT_EQ(batch.outcomes[1].second.status, Status::kNotFound);
  EXPECT_EQ(batch.outcomes[1].second.message, "no protected region 42");
  EXPECT_EQ(batch.outcomes[2].second.status, Status::kBadValue);
  EXPECT_FALSE(batch.changed());
  EXPECT_TRUE(regions.in_force().empty());
  EXPECT_FALSE(regions.write_for_append(batch).has_value());
  EXPECT_FALSE(batch.carried);
}

using test::ChunkStore;
using test::rock;

TEST(StoredChunkReader, AFailedReadIsNotedUntilAReadWorks) {
  ChunkStore store;
  store.chunks[{1, 2, 3}] = store::encode_chunk(rock());
  store.chunks[{4, 4, 4}] = {1, 2, 3};  // does not decode
  int before = 0;
  StoredChunkReader reader(store, std::chrono::milliseconds(500), [&] { ++before; });
  EXPECT_EQ(reader.read({1, 2, 3}).uniform_value().density, 1000);
  EXPECT_FALSE(reader.failing());
  const auto start = StoredChunkReader::Clock::now();
  for (const world::ChunkCoord c : {world::ChunkCoord{4, 4, 4}, world::ChunkCoord{9, 9, 9}}) {
    try {
      reader.read(c);
      ADD_FAILURE() << "read a chunk that is not there";
    } catch (const store::StoreError& e) {
      EXPECT_NE(std::string(e.what()).find("test store: chunk (" + std::to_string(c.x)),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_TRUE(reader.failing());
  EXPECT_NE(reader.last_error().find("missing from the store"), std::string::npos);
  EXPECT_TRUE(reader.backing_off(start));
  EXPECT_GE(reader.retry_at(), start + std::chrono::milliseconds(500));
  EXPECT_FALSE(reader.backing_off(reader.retry_at()));
  store.down = true;
  EXPECT_THROW(reader.read({1, 2, 3}), store::StoreError);
  EXPECT_NE(reader.last_error().find("database unreachable"), std::string::npos);
  store.down = false;
  reader.read({1, 2, 3});
  EXPECT_FALSE(reader.failing());
  EXPECT_EQ(before, store.reads);  // every read waited for the appends first
}

TEST(StoredChunkReader, TryLoadMakesTheChunkResidentAndModifiedOrSaysItFailed) {
  ChunkStore store;
  store.chunks[{0, 0, 0}] = store::encode_chunk(rock());
  StoredChunkReader reader(store, std::chrono::milliseconds(100), nullptr);
  WorldState state(1);
  state.read_stored = [&](world::ChunkCoord c) { return reader.read(c); };
  const auto now = StoredChunkReader::Clock::now();
  EXPECT_TRUE(reader.try_load(state, {0, 0, 0}, now));
  ASSERT_NE(state.chunks.find({0, 0, 0}), nullptr);
  EXPECT_TRUE(state.info.at({0, 0, 0}).modified);
  EXPECT_EQ(state.modified_count, 1u);
  EXPECT_FALSE(reader.try_load(state, {5, 0, 0}, now));
  EXPECT_EQ(state.chunks.find({5, 0, 0}), nullptr);
  EXPECT_TRUE(reader.failing());
}

// A chunk an edit changed, resident and unsaved, as the pipeline leaves it.
void edited_chunk(WorldState& state, Checkpoints& checkpoints, world::ChunkCoord c) {
  state.chunks.insert(c, rock());
  state.info[c] = {.modified = true, .unsaved = true};
  checkpoints.changed(c);
}

TEST(Checkpoints, AWrittenCheckpointStoresItsChunksAndTrimsTheLog) {
  ChunkStore store;
  WorldState state(1);
  const auto t0 = Checkpoints::Clock::now();
  Checkpoints checkpoints(store, false, {.interval = std::chrono::seconds(10)}, LogRetention{},
                          nullptr, t0);
  EXPECT_FALSE(checkpoints.has_unsaved());
  EXPECT_FALSE(checkpoints.due(t0 + std::chrono::hours(1)));  // nothing to write
  edited_chunk(state, checkpoints, {1, 0, 0});
  edited_chunk(state, checkpoints, {2, 0, 0});
  checkpoints.logged(5);
  EXPECT_EQ(checkpoints.log_tail(3), 8u);  // and 3 being appended
  EXPECT_FALSE(checkpoints.due(t0 + std::chrono::seconds(9)));
  ASSERT_TRUE(checkpoints.due(t0 + std::chrono::seconds(10)));
  const auto r = checkpoints.start(state, 5, t0 + std::chrono::seconds(10));
  ASSERT_TRUE(r.has_value());  // the pipeline's own connection: written at once
  EXPECT_TRUE(r->ok);
  EXPECT_EQ(r->coords.size(), 2u);
  EXPECT_TRUE(state.info.at({1, 0, 0}).checkpointing);  // until the result is taken in
  checkpoints.finish(state, *r, t0 + std::chrono::seconds(10));
  EXPECT_FALSE(state.info.at({1, 0, 0}).checkpointing);
  EXPECT_FALSE(state.info.at({1, 0, 0}).unsaved);
  EXPECT_EQ(state.stored.size(), 2u);
  EXPECT_FALSE(checkpoints.has_unsaved());
  EXPECT_EQ(checkpoints.log_tail(0), 0u);
  EXPECT_EQ(store.checkpoint_seq, 5u);
  EXPECT_EQ(store.trimmed_through, 5u);
  EXPECT_EQ(store.chunks.count({2, 0, 0}), 1u);
}

// A cluster node forgets a zone (docs/CLUSTER.md, "Evicting a zone's chunks") while a
// checkpoint holds one of its chunks: the chunk went back to the generated terrain, so the
// checkpoint must not mark it stored (it would be read back from the store when evicted);
// it was kept in memory for ever, unsaved, when it could not be marked.
TEST(Checkpoints, AChunkForgottenWhileACheckpointHoldsItIsNotMarkedStoredAndMayLeave) {
  ChunkStore store;
  WorldState state(1);
  const auto t0 = Checkpoints::Clock::now();
  Checkpoints checkpoints(store, false, {.interval = std::chrono::seconds(1)},
                          LogRetention{.keep_all = true}, nullptr, t0);
  edited_chunk(state, checkpoints, {1, 0, 0});
  edited_chunk(state, checkpoints, {2, 0, 0});
  const auto at = t0 + std::chrono::seconds(1);
  const auto r = checkpoints.start(state, 4, at);
  ASSERT_TRUE(r.has_value() && r->ok);
  state.info.at({2, 0, 0}) = {.modified = false, .unsaved = false, .checkpointing = true};
  checkpoints.forget({2, 0, 0});
  checkpoints.finish(state, *r, at);
  EXPECT_EQ(state.stored.count({1, 0, 0}), 1u);
  EXPECT_EQ(state.stored.count({2, 0, 0}), 0u);
  EXPECT_FALSE(state.info.at({2, 0, 0}).unsaved);  // evictable
  EXPECT_FALSE(state.info.at({2, 0, 0}).checkpointing);
  // Changed again later, the next checkpoint stores it as usual.
  edited_chunk(state, checkpoints, {2, 0, 0});
  const auto next = checkpoints.start(state, 6, at + std::chrono::seconds(1));
  ASSERT_TRUE(next.has_value() && next->ok);
  checkpoints.finish(state, *next, at + std::chrono::seconds(1));
  EXPECT_EQ(state.stored.count({2, 0, 0}), 1u);
}

TEST(Checkpoints, AFailedCheckpointLeavesItsChunksAndEditsUnsavedAndRestsBeforeTheNext) {
  ChunkStore store;
  store.fail_checkpoints = true;
  WorldState state(1);
  const auto t0 = Checkpoints::Clock::now();
  Checkpoints checkpoints(store, false,
                          {.interval = std::chrono::seconds(1), .retry = std::chrono::seconds(5)},
                          LogRetention{.keep_all = true}, nullptr, t0);
  edited_chunk(state, checkpoints, {0, 0, 7});
  checkpoints.logged(2);
  const auto at = t0 + std::chrono::seconds(1);
  const auto r = checkpoints.start(state, 2, at);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->ok);
  EXPECT_NE(r->error.find("disk full"), std::string::npos);
  checkpoints.logged(1);  // an edit made durable while it was written
  checkpoints.finish(state, *r, at);
  EXPECT_TRUE(state.info.at({0, 0, 7}).unsaved);
  EXPECT_TRUE(state.stored.empty());
  EXPECT_EQ(checkpoints.unsaved_chunks(), 1u);
  EXPECT_EQ(checkpoints.log_tail(0), 3u);                       // nothing of the log was trimmed
  EXPECT_FALSE(checkpoints.due(at + std::chrono::seconds(4)));  // the store rests
  EXPECT_TRUE(checkpoints.due(at + std::chrono::seconds(5)));
  store.fail_checkpoints = false;
  const auto again = checkpoints.start(state, 3, at + std::chrono::seconds(5));
  ASSERT_TRUE(again.has_value() && again->ok);
  EXPECT_EQ(store.trimmed_through, 0u);  // keep_log: the log stays whole
}

TEST(Checkpoints, TheLogIsFullAtItsBound) {
  ChunkStore store;
  Checkpoints checkpoints(store, false, {.max_log_tail = 10}, LogRetention{}, nullptr,
                          Checkpoints::Clock::now());
  EXPECT_FALSE(checkpoints.log_full(9));
  EXPECT_TRUE(checkpoints.log_full(10));
  EXPECT_FALSE(checkpoints.log_full(0));
}

TEST(ViewLoads, APlannedChunkWaitsForItsNeighbourhoodAndItsCallbackRunsOnceItIsMeshable) {
  const world::TerrainGenerator generator(4);
  WorldState state(1);
  // No background threads: the terrain a waiting chunk misses is generated here.
  ViewLoads loads(generator, state, nullptr, 0, 64, nullptr);
  const auto now = Clock::now();
  LoadPlan plan;
  EXPECT_EQ(loads.cost({0, 0, 0}, plan, now), ViewLoads::kMeshWork + 27 * ViewLoads::kGenerateWork);
  EXPECT_EQ(loads.cost({0, 0, 0}, plan, now), 0u);  // planned already
  // A neighbour shares 18 of its 27 chunks: only the others cost.
  EXPECT_EQ(loads.cost({1, 0, 0}, plan, now), ViewLoads::kMeshWork + 9 * ViewLoads::kGenerateWork);
  bool done = false;
  std::vector<LoadSlice> slices{
      {.owner = 7, .chunks = {{0, 0, 0}, {1, 0, 0}}, .done = [&] { done = true; }}};
  loads.wait_for(slices, plan);
  EXPECT_EQ(loads.waiting_count(), 2u);
  EXPECT_EQ(state.pins.count({0, 0, 0}), 1u);  // pinned against eviction meanwhile
  loads.run_finished();
  EXPECT_FALSE(done);
  BatchCounts counts;
  std::vector<world::ChunkCoord> meshable = loads.take_meshable(now, counts);
  std::sort(meshable.begin(), meshable.end());
  EXPECT_EQ(meshable, (std::vector<world::ChunkCoord>{{0, 0, 0}, {1, 0, 0}}));
  EXPECT_EQ(counts.chunks_generated, 36u);
  EXPECT_FALSE(loads.waiting());
  EXPECT_TRUE(state.pins.empty());
  loads.run_finished();
  EXPECT_TRUE(done);
}

TEST(ViewLoads, AWaitingChunkNoViewHoldsIsDroppedButAOneOffLoadKeepsItsOwn) {
  const world::TerrainGenerator generator(4);
  WorldState state(1);
  ViewLoads loads(generator, state, nullptr, 0, 64, nullptr);
  const auto now = Clock::now();
  LoadPlan plan;
  loads.cost({5, 0, 0}, plan, now);
  loads.cost({9, 0, 0}, plan, now);
  bool one_off_done = false;
  std::vector<LoadSlice> slices{{.owner = 3, .chunks = {{5, 0, 0}}},
                                {.owner = BatchScheduler::kUnlimitedOwners | 1,
                                 .chunks = {{9, 0, 0}},
                                 .done = [&] { one_off_done = true; }}};
  loads.wait_for(slices, plan);
  loads.drop_unviewed();  // owner 3's view holds nothing: it moved on, or closed
  EXPECT_EQ(loads.waiting_count(), 1u);
  EXPECT_EQ(state.pins.count({5, 0, 0}), 0u);
  state.views.set(3, {5, 0, 0}, 1);  // a view that holds it keeps it waiting
  LoadPlan again;
  loads.cost({5, 0, 0}, again, now);
  std::vector<LoadSlice> more{{.owner = 3, .chunks = {{5, 0, 0}}}};
  loads.wait_for(more, again);
  loads.drop_unviewed();
  EXPECT_EQ(loads.waiting_count(), 2u);
  loads.run_all_callbacks();  // at stop
  EXPECT_TRUE(one_off_done);
}

// The store came back in the middle of a pass: one neighbour's read failed, a later one's
// worked (and ended the reader's failure). The chunk still waits for the first, so the
// pipeline must pass again: it asks waiting_for_store(), not the reader. (Under load a
// TSan run once left such a load waiting for good.)
TEST(ViewLoads, AChunkWaitingForAFailedStoredNeighbourIsRetriedAfterAnotherReadWorked) {
  const world::TerrainGenerator generator(4);
  WorldState state(1);
  ChunkStore store;
  store.chunks[{1, 1, 1}] = store::encode_chunk(rock());  // read last: it works
  StoredChunkReader reader(store, std::chrono::milliseconds(10), nullptr);
  state.read_stored = [&](world::ChunkCoord c) { return reader.read(c); };
  state.stored = {{-1, -1, -1}, {1, 1, 1}};  // (-1, -1, -1) is read first: missing, it fails
  ViewLoads loads(generator, state, &reader, 0, 64, nullptr);
  const auto now = Clock::now();
  LoadPlan plan;
  loads.cost({0, 0, 0}, plan, now);
  std::vector<LoadSlice> slices{{.owner = BatchScheduler::kUnlimitedOwners, .chunks = {{0, 0, 0}}}};
  loads.wait_for(slices, plan);
  std::vector<world::ChunkCoord> others;  // resident already: only the two stored ones are read
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        if (!state.stored.count({dx, dy, dz})) others.push_back({dx, dy, dz});
  state.ensure_loaded(others, generator, now);
  BatchCounts counts;
  EXPECT_TRUE(loads.take_meshable(now, counts).empty());
  EXPECT_FALSE(reader.failing());  // the last read worked
  EXPECT_TRUE(loads.waiting_for_store());
  store.chunks[{-1, -1, -1}] = store::encode_chunk(rock());  // the store gives it back
  EXPECT_EQ(loads.take_meshable(now, counts), (std::vector<world::ChunkCoord>{{0, 0, 0}}));
  EXPECT_FALSE(loads.waiting_for_store());
}

constexpr size_t kMiB = size_t{1} << 20;
using std::chrono::milliseconds;
using std::chrono::seconds;

TEST(MemoryKeeper, APeriodicPassEveryQuarterOfEvictAfterDropsOnlyIdleChunks) {
  const auto t0 = MemoryKeeper::Clock::now();
  MemoryKeeper keeper(MemoryBudget(100 * kMiB), seconds(120), seconds(1), t0);
  EXPECT_FALSE(keeper.due(t0 + seconds(29), 10 * kMiB, 0));
  const auto pass = keeper.due(t0 + seconds(31), 10 * kMiB, 0);
  ASSERT_TRUE(pass.has_value());
  EXPECT_EQ(pass->target_bytes, SIZE_MAX);  // idle ones only
  EXPECT_EQ(pass->max_scan, SIZE_MAX);
  EXPECT_EQ(pass->idle, seconds(120));
  keeper.evicted(t0 + seconds(31), 3, 10 * kMiB);
  EXPECT_FALSE(keeper.due(t0 + seconds(32), 10 * kMiB, 0));
}

TEST(MemoryKeeper, UnderPressureItEvictsAfterEveryBatchWhileThatHelpsAndRarelyWhenNot) {
  const auto t0 = MemoryKeeper::Clock::now();
  MemoryKeeper keeper(MemoryBudget(100 * kMiB), seconds(120), seconds(1), t0);
  const auto pass = keeper.due(t0, 95 * kMiB, 10 * kMiB);  // over 90 %
  ASSERT_TRUE(pass.has_value());
  EXPECT_EQ(pass->target_bytes, MemoryBudget(100 * kMiB).evict_target(10 * kMiB));
  EXPECT_EQ(pass->max_scan, MemoryKeeper::kPressureScan);
  keeper.evicted(t0, 0, 95 * kMiB);  // freed nothing: everything is in use
  EXPECT_FALSE(keeper.due(t0 + milliseconds(100), 95 * kMiB, 10 * kMiB));
  EXPECT_TRUE(keeper.due(t0 + milliseconds(100), 96 * kMiB, 10 * kMiB));  // the world grew
  EXPECT_TRUE(keeper.due(t0 + MemoryKeeper::kPressureRetry + milliseconds(1), 95 * kMiB, 0));
  keeper.evicted(t0 + seconds(1), 7, 93 * kMiB);  // it freed some: again after the next batch
  EXPECT_TRUE(keeper.due(t0 + seconds(1) + milliseconds(1), 93 * kMiB, 10 * kMiB));
  EXPECT_FALSE(keeper.due(t0 + seconds(1) + milliseconds(1), 50 * kMiB, 10 * kMiB));
}

TEST(MemoryKeeper, EditsGetOneEvictionPerBatchAndLoadsWaitAtTheBudget) {
  MemoryKeeper keeper(MemoryBudget(100 * kMiB), seconds(120), seconds(1),
                      MemoryKeeper::Clock::now());
  const auto pass = keeper.for_edits(5 * kMiB, 10 * kMiB);
  ASSERT_TRUE(pass.has_value());
  EXPECT_EQ(pass->target_bytes, MemoryBudget(100 * kMiB).evict_target(10 * kMiB) - 5 * kMiB);
  EXPECT_GE(pass->min_age, milliseconds(1));  // what this batch used stays
  EXPECT_FALSE(keeper.for_edits(kMiB, 0));    // refused: the scan ran once this batch
  keeper.new_batch();
  EXPECT_TRUE(keeper.for_edits(kMiB, 0));

  EXPECT_EQ(keeper.next_look(false), seconds(30));
  EXPECT_EQ(keeper.next_look(true), MemoryKeeper::kBudgetRetry);
  EXPECT_FALSE(keeper.update_blocked(99 * kMiB));  // unchanged: loads go on
  EXPECT_TRUE(keeper.update_blocked(100 * kMiB));
  EXPECT_TRUE(keeper.loads_blocked());

  EXPECT_EQ(keeper.next_look(true), MemoryKeeper::kPressureRetry);
  EXPECT_TRUE(keeper.update_blocked(50 * kMiB));
  EXPECT_FALSE(keeper.loads_blocked());
}

// The attack mix held the accounted bytes under 90 % of a 1 GiB budget while the resident
// set reached 1,105 MiB: the allocator's heap beyond the parts (structures no part counts,
// what size classes waste) was never counted.
TEST(MemoryKeeper, TheResidentSetWentPastTheBudgetWhileTheHeapBeyondThePartsWasNotCounted) {
  const auto t0 = MemoryKeeper::Clock::now();
  MemoryKeeper keeper(MemoryBudget(100 * kMiB), seconds(120), seconds(1), t0);
  keeper.set_session_bytes(2 * kMiB);
  EXPECT_TRUE(keeper.heap_due(t0));
  keeper.heap_measured(t0, 97 * kMiB, 85 * kMiB);  // the allocator holds 12 MiB more
  EXPECT_EQ(keeper.unaccounted_bytes(), 12 * kMiB);
  EXPECT_EQ(keeper.other_bytes(), 14 * kMiB);
  EXPECT_FALSE(keeper.heap_due(t0 + milliseconds(999)));  // looked at once a second
  EXPECT_TRUE(keeper.heap_due(t0 + MemoryKeeper::kHeapLook));
  // Parts of 80 MiB with the rest (14) are over 90 %: a pass, down to 80 % of it all.
  const size_t other = keeper.other_bytes();
  const auto pass = keeper.due(t0 + seconds(1), 80 * kMiB + other, other);
  ASSERT_TRUE(pass.has_value());
  EXPECT_EQ(pass->target_bytes, MemoryBudget(100 * kMiB).evict_target(14 * kMiB));
  EXPECT_FALSE(keeper.update_blocked(80 * kMiB + other));  // loads go on below the budget
  EXPECT_TRUE(keeper.update_blocked(87 * kMiB + other));   // and wait past it
  // Parts accounting more than the allocator holds leave nothing unaccounted.
  keeper.heap_measured(t0 + seconds(1), 50 * kMiB, 60 * kMiB);
  EXPECT_EQ(keeper.unaccounted_bytes(), 0u);
}

TEST(Inbox, AfterStopNothingIsQueuedAndTheTaskIsLeftToTheCaller) {
  Inbox inbox{BatchScheduler()};
  bool answered = false;
  OrderedTask task = EditTask{.edit = world::Explosion{{0, 0, 0}, 2, 1},
                              .done = [&](const EditResult&) { answered = true; }};
  EXPECT_TRUE(inbox.add(task));
  EXPECT_EQ(inbox.counts().edits, 1u);
  inbox.stop();
  OrderedTask late = EditTask{.edit = world::Explosion{{0, 0, 0}, 2, 1},
                              .done = [&](const EditResult&) { answered = true; }};
  EXPECT_FALSE(inbox.add(late));
  std::get<EditTask>(late).done(EditResult{});  // still the caller's to answer
  EXPECT_TRUE(answered);
  std::function<void()> done = [] {};
  EXPECT_FALSE(inbox.add_load({{0, 0, 0}}, done));
  EXPECT_TRUE(done);  // not taken
  EXPECT_EQ(inbox.counts().edits, 1u);
}

TEST(Inbox, AWakeUpEndsTheWaitAndNoneIsLostBetweenTheLookAndTheWait) {
  Inbox inbox{BatchScheduler()};
  const auto landed = [](Inbox::State& in) { return in.append_landed; };
  const auto long_wait = [](const Inbox::State&) { return seconds(30); };
  std::thread appender([&] {
    std::this_thread::sleep_for(milliseconds(50));
    inbox.append_landed();
  });
  const auto start = Clock::now();
  while (!inbox.wait_unless(landed, long_wait)) {
  }
  appender.join();
  EXPECT_LT(Clock::now() - start, seconds(10));
  inbox.append_landed();  // before anyone waits: the next look sees it
  EXPECT_TRUE(inbox.wait_unless(landed, long_wait));
}

TEST(Inbox, ViewsAndTheirDropsWaitForThePipelineToTakeThem) {
  Inbox inbox{BatchScheduler()};
  EXPECT_FALSE(inbox.set_view(5, {1, 2, 3}, 2, {{1, 2, 3}}, 0));  // nothing replaced
  inbox.set_lod_view(5, {LodKey{}});
  inbox.locked([](Inbox::State& in) {
    EXPECT_EQ(in.view_updates.at(5), (std::pair<world::ChunkCoord, int>{{1, 2, 3}, 2}));
    EXPECT_EQ(in.lod_updates.at(5).size(), 1u);
    EXPECT_TRUE(in.scheduler.has_loads());
  });
  inbox.drop_view(5);
  inbox.locked([](Inbox::State& in) {
    EXPECT_EQ(in.view_updates.at(5).second, -1);  // dropped
    EXPECT_TRUE(in.lod_updates.at(5).empty());
    EXPECT_FALSE(in.scheduler.has_loads());
  });
}

TEST(Subscribers, EachHearsWhatWasPublishedUntilItLeaves) {
  Subscribers subscribers;
  std::vector<world::ChunkCoord> heard;
  std::vector<LodKey> heard_lod;
  const uint64_t a = subscribers.subscribe([&](const std::vector<world::ChunkCoord>& published) {
    heard.insert(heard.end(), published.begin(), published.end());
  });
  const uint64_t b = subscribers.subscribe_lod([&](const LodPublication& p) {
    heard_lod.insert(heard_lod.end(), p.keys.begin(), p.keys.end());
  });
  EXPECT_NE(a, b);
  subscribers.notify({{1, 2, 3}});
  subscribers.notify({});  // nothing published: nobody called
  subscribers.notify_lod({.keys = {LodKey{}}});
  EXPECT_EQ(heard, (std::vector<world::ChunkCoord>{{1, 2, 3}}));
  EXPECT_EQ(heard_lod.size(), 1u);
  subscribers.unsubscribe(a);
  subscribers.unsubscribe(b);
  subscribers.notify({{4, 5, 6}});
  subscribers.notify_lod({.keys = {LodKey{}}});
  EXPECT_EQ(heard.size(), 1u);
  EXPECT_EQ(heard_lod.size(), 1u);
}

}  // namespace
}  // namespace vox::pipeline
