// The pipeline's passes as functions, with no pipeline around them: a batch's edit pass
// (server/pipeline/edit_pass.hpp) and its undo (edit_step.hpp), re-meshing and publication
// (remesh.hpp), the world restored from a store (world_restore.hpp), the checkpoints' turn
// between batches (checkpoints.hpp), the LOD stage held back (lod_stage.hpp) and the
// stats book (stats_book.hpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <vector>

#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/edit_pass.hpp"
#include "server/pipeline/lod_stage.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/remesh.hpp"
#include "server/pipeline/stats_book.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/world_restore.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"
#include "tests/chunk_store_stub.hpp"

namespace vox::pipeline {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using test::ChunkStore;

// The world an edit pass works on: fresh state, the generator, a memory keeper without a
// budget, a mesh store and (optionally) checkpoints over a stub store.
struct PassWorld {
  explicit PassWorld(bool durable, size_t budget = 0)
      : memory(MemoryBudget(budget), seconds(60), seconds(1), Clock::now()) {
    if (durable)
      checkpoints = std::make_unique<Checkpoints>(store, false, CheckpointLimits{.max_log_tail = 4},
                                                  LogRetention{}, nullptr, Clock::now());
  }
  EditWorld access() {
    return {state, generator, memory, meshes, checkpoints.get(), 0, [this] {
              return state.chunks.memory_bytes();
            }};
  }
  EditRules rules(bool resting = false, uint64_t log_tail = 0) const {
    return {.limits = limits,
            .max_generated_per_owner = 400,
            .durable = checkpoints != nullptr,
            .store_resting = resting,
            .log_tail = log_tail};
  }
  ChunkStore store;
  WorldState state{1};
  world::TerrainGenerator generator{7};
  MemoryKeeper memory;
  MeshStore meshes;
  std::unique_ptr<Checkpoints> checkpoints;
  world::EditLimits limits;
  ProtectedRegions regions{limits};
};

// The chunks around the origin resident, and those nearest it meshed (a view holds them):
// an edit there dirties their meshes.
void viewed(PassWorld& w) {
  std::vector<world::ChunkCoord> around;
  for (int z = -2; z <= 2; ++z)
    for (int y = -2; y <= 2; ++y)
      for (int x = -2; x <= 2; ++x) around.push_back({x, y, z});
  w.state.ensure_loaded(around, w.generator, Clock::now());
  for (const world::ChunkCoord& c : around) {
    if (std::abs(c.x) <= 1 && std::abs(c.y) <= 1 && std::abs(c.z) <= 1)
      w.state.info[c].meshed = true;
  }
}

std::vector<OrderedTask> tasks_of(std::vector<world::Edit> edits) {
  std::vector<OrderedTask> tasks;
  for (auto& e : edits)
    tasks.emplace_back(std::in_place_type<EditTask>, EditTask{.edit = std::move(e)});
  return tasks;
}

const world::Edit kCrater = world::Explosion{{4, 2, 4}, 6, 2};

TEST(EditPass, AValidEditIsAppliedWithItsDirtyChunksUndoAndEditTime) {
  PassWorld w(true);
  viewed(w);
  auto tasks = tasks_of({kCrater});
  const Clock::time_point submitted = Clock::now() - milliseconds(5);
  std::get<EditTask>(tasks[0]).submitted = submitted;
  EditWorld access = w.access();
  EditBatch b = apply_edits(tasks, access, w.regions, w.rules(), Clock::now());
  ASSERT_TRUE(b.results[0].accepted) << b.results[0].message;
  EXPECT_TRUE(b.any_edit);
  EXPECT_EQ(b.accepted.size(), 1u);
  EXPECT_FALSE(b.dirty.empty());
  EXPECT_FALSE(b.undo.patches.empty());  // durable: what it overwrote is kept
  EXPECT_EQ(b.counts.edits_applied, 1u);
  EXPECT_EQ(b.edited_at.at(b.dirty.front()), submitted);
  EXPECT_GT(w.checkpoints->unsaved_chunks(), 0u);  // the next checkpoint writes them
}

// A query answered in place: once all queries have had their share of the thread, the next
// is refused with a time to come back, and a query never loads more than its share of
// terrain (kLoadsPerQuery; the rest on the next ask) nor faster than the budget's rate.
TEST(QueryPass, QueriesShareTheThreadAndTheirLoadsAndSayWhenToAskAgain) {
  PassWorld w(false);
  EditWorld access = w.access();
  const Clock::time_point now = Clock::now();
  QueryAnswer answer;
  const auto ask = [&](mesh::Ray ray, QueryBudget* budget) {
    QueryTask task;
    task.ray = ray;
    task.done = [&](const QueryAnswer& a) { answer = a; };
    answer_query(task, access, budget, now);
    EXPECT_FALSE(task.done);  // dropped once called
    return answer;
  };
  // Straight down through 20 chunks of sky and ground, none in memory.
  const mesh::Ray down{{5.5f, 620, 5.5f}, {0, -1, 0}, 640};
  QueryBudget budget;
  QueryAnswer a = ask(down, &budget);
  EXPECT_EQ(a.reason, world::RefusalReason::kOverBudget) << a.message;
  EXPECT_EQ(w.state.chunks.size(), QueryBudget::kLoadsPerQuery);  // those loaded stay
  a = ask(down, &budget);
  EXPECT_EQ(a.reason, world::RefusalReason::kNone) << a.message;
  EXPECT_TRUE(a.hit.hit);
  // The thread's share spent (a long query overdrew it): refused, with when to come back.
  budget.seconds.charge(0.2, now);
  a = ask(down, &budget);
  EXPECT_EQ(a.reason, world::RefusalReason::kServerBusy);
  EXPECT_GE(a.retry_after_ms, 1500u);  // 0.15 s of debt at 0.1 s a second
  EXPECT_LE(a.retry_after_ms, 2600u);
  // The loads' rate spent: a query reaching new terrain is refused at once.
  QueryBudget slow;
  slow.loads = TokenBucket(1, 1, now);
  a = ask({{2000.5f, 40, 2000.5f}, {0, -1, 0}, 80}, &slow);
  EXPECT_EQ(a.reason, world::RefusalReason::kServerBusy) << a.message;
  EXPECT_GT(a.retry_after_ms, 0u);
}

TEST(EditPass, RefusalsSayWhyAndLeaveTheWorldAsItWas) {
  PassWorld w(true);
  world::Edit too_big = world::Explosion{{0, 0, 0}, 1000, 1};
  EditWorld access = w.access();
  // Invalid, then the store resting, then the log at its bound (4 logged, none checkpointed).
  auto invalid = tasks_of({too_big});
  EditBatch a = apply_edits(invalid, access, w.regions, w.rules(), Clock::now());
  EXPECT_EQ(a.results[0].reason, world::RefusalReason::kBadRadius);
  auto resting = tasks_of({kCrater});
  EditBatch b = apply_edits(resting, access, w.regions, w.rules(true), Clock::now());
  EXPECT_EQ(b.results[0].reason, world::RefusalReason::kStorageUnavailable);
  EXPECT_EQ(b.results[0].message, kStorageMessage);
  auto behind = tasks_of({kCrater});
  EditBatch c = apply_edits(behind, access, w.regions, w.rules(false, 4), Clock::now());
  EXPECT_EQ(c.results[0].reason, world::RefusalReason::kServerBusy);
  EXPECT_EQ(c.counts.edits_refused_busy, 1u);
  for (const EditBatch* batch : {&a, &b, &c}) {
    EXPECT_FALSE(batch->results[0].accepted);
    EXPECT_TRUE(batch->dirty.empty());
    EXPECT_EQ(batch->counts.edits_refused, 1u);
  }
  EXPECT_EQ(w.state.chunks.size(), 0u);  // nothing was even loaded
}

TEST(EditPass, OneSendersTerrainIsCappedPerBatchButAnotherSendersIsNot) {
  PassWorld w(false);
  std::vector<OrderedTask> tasks;
  for (LoadOwner owner : {LoadOwner{1}, LoadOwner{1}, LoadOwner{2}}) {
    const float x = static_cast<float>(tasks.size()) * 200;  // each far from the others
    tasks.emplace_back(std::in_place_type<EditTask>,
                       EditTask{.edit = world::Explosion{{x, 0, 0}, 6, 1}, .owner = owner});
  }
  EditWorld access = w.access();
  EditRules rules = w.rules();
  rules.max_generated_per_owner = 10;  // one crater's terrain, not two
  EditBatch b = apply_edits(tasks, access, w.regions, rules, Clock::now());
  EXPECT_TRUE(b.results[0].accepted);
  EXPECT_GT(b.results[0].chunks_generated, 6u);  // a crater across chunk corners
  EXPECT_EQ(b.results[1].reason, world::RefusalReason::kOverBudget);
  EXPECT_TRUE(b.results[2].accepted);
}

TEST(EditPass, AnInspectionSeesTheEditsQueuedBeforeIt) {
  PassWorld w(false);
  auto tasks = tasks_of({kCrater});
  world::Sample seen{};
  tasks.emplace_back(std::in_place_type<InspectTask>,
                     InspectTask{[&](bool) { seen = w.state.chunks.sample_at(4, 2, 4); }});
  EditWorld access = w.access();
  apply_edits(tasks, access, w.regions, w.rules(), Clock::now());
  EXPECT_LT(seen.density, world::TerrainGenerator(7).sample_at(4, 2, 4).density);
}

TEST(EditStep, UndoingABatchGivesBackEverySampleAndFlag) {
  PassWorld w(true);
  viewed(w);
  auto first = tasks_of({world::Explosion{{40, 2, 40}, 4, 1}});
  EditWorld access = w.access();
  apply_edits(first, access, w.regions, w.rules(), Clock::now());
  std::vector<world::Sample> before;
  const auto each_sample = [&](auto fn) {
    for (int z = -8; z <= 16; ++z)
      for (int y = -8; y <= 12; ++y)
        for (int x = -8; x <= 16; ++x) fn(w.state.chunks.sample_at(x, y, z));
  };
  each_sample([&](world::Sample s) { before.push_back(s); });
  const size_t modified = w.state.modified_count;
  const size_t unsaved = w.checkpoints->unsaved_chunks();
  auto second = tasks_of({kCrater, world::Brush{{5, 3, 5}, 5, 1, false, world::Material{4}}});
  EditBatch b = apply_edits(second, access, w.regions, w.rules(), Clock::now());
  ASSERT_TRUE(b.results[0].accepted && b.results[1].accepted);
  undo_edits(w.state, w.checkpoints.get(), b.undo);
  EXPECT_TRUE(b.undo.patches.empty());
  EXPECT_EQ(w.state.modified_count, modified);
  EXPECT_EQ(w.checkpoints->unsaved_chunks(), unsaved);
  size_t i = 0, differ = 0;
  each_sample([&](world::Sample s) { differ += s == before[i++] ? 0 : 1; });
  EXPECT_EQ(differ, 0u);
}

TEST(Remesh, AnUnchangedMeshIsNotPublishedAndVersionsGrow) {
  PassWorld w(false);
  viewed(w);
  std::vector<world::ChunkCoord> dirty;
  const auto crater = [&] {  // applied, re-meshed and published; the chunks published
    auto tasks = tasks_of({kCrater});
    EditWorld access = w.access();
    EditBatch b = apply_edits(tasks, access, w.regions, w.rules(), Clock::now());
    FreshMeshes fresh = remesh(w.state, b.dirty, w.meshes, nullptr);
    dirty = b.dirty;
    return publish(w.state, w.meshes, b.dirty, fresh, &b.edited_at);
  };
  const std::vector<world::ChunkCoord> published = crater();
  ASSERT_FALSE(published.empty());
  const uint64_t version = w.meshes.get(published.front())->version;
  FreshMeshes same = remesh(w.state, dirty, w.meshes, nullptr);
  for (const auto& m : same) EXPECT_EQ(m, nullptr);  // nothing changed since
  const std::vector<world::ChunkCoord> republished = crater();
  ASSERT_FALSE(republished.empty());
  EXPECT_GT(w.meshes.get(republished.front())->version, version);
}

TEST(Remesh, AnEditBatchDoesNotPublishAChunkEvictedWhileItWaited) {
  PassWorld w(false);
  viewed(w);
  auto tasks = tasks_of({kCrater});
  EditWorld access = w.access();
  EditBatch b = apply_edits(tasks, access, w.regions, w.rules(), Clock::now());
  ASSERT_FALSE(b.dirty.empty());
  FreshMeshes fresh = remesh(w.state, b.dirty, w.meshes, nullptr);
  // Evicted while the batch waited for the store, and loaded again: not meshed any more.
  for (const world::ChunkCoord& c : b.dirty) w.state.info[c].meshed = false;
  EXPECT_TRUE(publish(w.state, w.meshes, b.dirty, fresh, &b.edited_at).empty());
  EXPECT_EQ(w.meshes.size(), 0u);
}

TEST(WorldRestore, TheLogAfterTheCheckpointIsReplayedInOrderAndNumberingGoesOn) {
  ChunkStore store;
  store.world_info = {.last_seq = 9, .checkpoint_seq = 6};
  store.logged = {{.seq = 5, .edit = world::Explosion{{900, 0, 0}, 4, 1}},
                  {.seq = 7, .edit = kCrater},
                  {.seq = 8, .edit = world::Paint{{4, 0, 4}, 3, 9}}};
  PassWorld w(false);
  StoredChunkReader reader(store, milliseconds(100), nullptr);
  EditWorld access = w.access();
  const RestoredWorld r = restore_world(store, access, w.regions, reader);
  EXPECT_EQ(r.replayed, 2u);  // edit 5 is in the checkpoint
  EXPECT_EQ(r.next_seq, 10u);
  EXPECT_GT(w.state.modified_count, 0u);
  // The same edits applied by hand give the same samples.
  PassWorld hand(false);
  auto tasks = tasks_of({kCrater, world::Paint{{4, 0, 4}, 3, 9}});
  EditWorld hand_access = hand.access();
  apply_edits(tasks, hand_access, hand.regions, hand.rules(), Clock::now());
  for (int x = -4; x <= 12; ++x)
    EXPECT_EQ(w.state.chunks.sample_at(x, 2, 4), hand.state.chunks.sample_at(x, 2, 4)) << x;
}

TEST(WorldRestore, ALoggedEditThatCannotApplyAgainStopsTheStartWithItsNumber) {
  ChunkStore store;
  store.logged = {{.seq = 3, .edit = kCrater}};
  PassWorld w(false, 1);  // a budget of one byte
  StoredChunkReader reader(store, milliseconds(100), nullptr);
  EditWorld access = w.access();
  try {
    restore_world(store, access, w.regions, reader);
    ADD_FAILURE() << "restored a world that does not fit";
  } catch (const store::StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("logged edit 3 cannot be applied again"),
              std::string::npos)
        << e.what();
  }
}

TEST(Checkpoints, ATurnAnswersTheBatchesInFlightBeforeItStartsOrTakesInACheckpoint) {
  ChunkStore store;
  WorldState state(1);
  const auto t0 = Checkpoints::Clock::now();
  Checkpoints checkpoints(store, false, {.interval = seconds(10)}, LogRetention{}, nullptr, t0);
  int drains = 0;
  const auto drain = [&] {
    ++drains;
    return uint64_t{12};
  };
  state.chunks.insert({1, 0, 0}, test::rock());
  state.info[{1, 0, 0}] = {.modified = true, .unsaved = true};
  checkpoints.changed({1, 0, 0});
  checkpoints.logged(3);
  std::vector<CheckpointResult> done;
  // Each finished checkpoint is heard of at once, its chunks already marked stored.
  const auto finished = [&](const CheckpointResult& r) {
    EXPECT_FALSE(state.info.at({1, 0, 0}).checkpointing);
    done.push_back(r);
  };
  checkpoints.turn(state, t0 + seconds(9), drain, finished);
  EXPECT_TRUE(done.empty());
  EXPECT_EQ(drains, 0);  // not due: the batches in flight go on
  checkpoints.turn(state, t0 + seconds(10), drain, finished);
  EXPECT_EQ(drains, 1);
  ASSERT_EQ(done.size(), 1u);  // the pipeline's own connection: written and taken in
  EXPECT_TRUE(done[0].ok);
  EXPECT_EQ(done[0].seq, 12u);
  EXPECT_EQ(store.checkpoint_seq, 12u);
  EXPECT_FALSE(state.info.at({1, 0, 0}).checkpointing);
  EXPECT_FALSE(checkpoints.has_unsaved());
}

TEST(Checkpoints, TheLastOneAtStopWritesEverythingUnsaved) {
  ChunkStore store;
  WorldState state(1);
  Checkpoints checkpoints(store, false, {.interval = seconds(3600)}, LogRetention{}, nullptr,
                          Clock::now());
  for (int x = 0; x < 3; ++x) {
    state.chunks.insert({x, 0, 0}, test::rock());
    state.info[{x, 0, 0}] = {.modified = true, .unsaved = true};
    checkpoints.changed({x, 0, 0});
  }
  std::vector<CheckpointResult> done;
  const auto finished = [&](const CheckpointResult& r) { done.push_back(r); };
  checkpoints.last(state, 40, finished);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].coords.size(), 3u);
  EXPECT_EQ(store.chunks.size(), 3u);
  EXPECT_EQ(store.checkpoint_seq, 40u);
  EXPECT_FALSE(checkpoints.has_unsaved());
  checkpoints.last(state, 40, finished);
  EXPECT_EQ(done.size(), 1u);  // nothing more to write
}

TEST(LodStage, HeldBackForItsStarvationTimeItAsksForTheStoreAndARunStartsTheClockAgain) {
  world::TerrainGenerator generator(3);
  WorldState state(1);
  LodStage lod(generator, state, {});
  const auto t0 = Clock::now();
  EXPECT_FALSE(lod.held_back(t0));
  EXPECT_FALSE(lod.held_back(t0 + LodStage::kStarvation - milliseconds(1)));
  EXPECT_TRUE(lod.held_back(t0 + LodStage::kStarvation));
  lod.ran();
  EXPECT_FALSE(lod.held_back(t0 + LodStage::kStarvation * 2));
}

// Level-1 keys without seams: `count` chunks in a row along x from chunk `x0`, through
// the surface.
std::vector<LodKey> row_of_keys(int x0, int count) {
  std::vector<LodKey> keys;
  for (int x = x0; x < x0 + count; ++x) keys.push_back({{1, {x, -1, 0}}, {}});
  return keys;
}

// The order a stage publishes the keys it is asked for, two at a time.
std::vector<LodKey> publication_order(LodStage& lod, Clock::time_point now, size_t expected) {
  std::vector<LodKey> order;
  for (int pass = 0; pass < 100 && order.size() < expected; ++pass) {
    const LodStage::RunResult r = lod.run(now, 2);
    order.insert(order.end(), r.published.begin(), r.published.end());
  }
  return order;
}

size_t position(const std::vector<LodKey>& order, const LodKey& k) {
  return static_cast<size_t>(std::find(order.begin(), order.end(), k) - order.begin());
}

// Two owners asking for 8 keys each, 7 before 9, and the order a stage publishes them in
// when it runs at `now`.
struct TwoOwners {
  std::vector<LodKey> early = row_of_keys(0, 8), late = row_of_keys(20, 8);
  std::vector<LodKey> order;
};
TwoOwners publish_for_two_owners(Clock::time_point now) {
  world::TerrainGenerator generator(3);
  WorldState state(2);
  LodStage lod(generator, state, {});
  TwoOwners t;
  lod.set_wants(7, t.early);
  lod.set_wants(9, t.late);
  t.order = publication_order(lod, now, 16);
  return t;
}

// 200 joining players each waited for the whole crowd's backlog: the stage took four keys
// from every owner in turn, so every layout was finished near the end. The owner that
// came first is served first while their first views wait.
TEST(LodStage, TheFirstViewOfThePlayerWhoCameFirstIsMeshedFirst) {
  const TwoOwners t = publish_for_two_owners(Clock::now());
  ASSERT_EQ(t.order.size(), 16u);
  for (const LodKey& k : t.early) EXPECT_LT(position(t.order, k), 8u) << "an early key came late";
}

// ...but not for ever: a client that keeps its first view from completing (changing its
// layout, say) loses its place after kFirstViewPriority, and the owners share in turn.
TEST(LodStage, AFirstViewKeepsItsPlaceForTenSecondsAtMost) {
  const TwoOwners t =
      publish_for_two_owners(Clock::now() + LodStage::kFirstViewPriority + seconds(1));
  ASSERT_EQ(t.order.size(), 16u);
  EXPECT_LT(position(t.order, t.late.front()), 8u) << "the later owner waited for the first";
}

TEST(StatsBook, CountsAddToTheTotalsAndToTheBatchInHandOnly) {
  StatsBook book;
  WorldState state(1);
  state.chunks.insert({0, 0, 0}, test::rock());
  book.count({.edits_applied = 2, .edits_refused = 1, .edits_refused_busy = 1}, state, 5);
  book.start_batch();
  book.count({.edits_applied = 3, .meshes_published = 4}, state, 6);
  EXPECT_EQ(book.batch().edits_applied, 3u);
  EXPECT_EQ(book.batch().edits_refused, 0u);
  const PipelineStats s = book.snapshot();
  EXPECT_EQ(s.edits_applied, 5u);
  EXPECT_EQ(s.edits_refused, 1u);
  EXPECT_EQ(s.edits_refused_busy, 1u);
  EXPECT_EQ(s.meshes_published, 4u);
  EXPECT_EQ(s.loaded_chunks, 1u);
  EXPECT_EQ(s.unsaved_chunks, 6u);
}

}  // namespace
}  // namespace vox::pipeline
