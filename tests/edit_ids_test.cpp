// Edit ids (docs/PROTOCOL.md 4.4, Edit.edit_id): a resend of an edit already applied is
// answered ACCEPTED with already_applied and changes nothing; an edit undone because its
// append failed is not remembered (its resend applies it); the memory is bounded.
#include "server/pipeline/edit_ids.hpp"

#include <gtest/gtest.h>

#include <future>
#include <memory>
#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/gated_store.hpp"
#include "tests/pipeline_test_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::pipeline {
namespace {

TEST(EditIds, RemembersTheLastNotedAndForgetsTheOldestFirst) {
  EditIds ids(3);
  EXPECT_FALSE(ids.has(0));
  ids.note(0);  // none
  EXPECT_EQ(ids.size(), 0u);
  for (uint64_t id = 1; id <= 4; ++id) ids.note(id);
  EXPECT_FALSE(ids.has(1));
  EXPECT_TRUE(ids.has(2) && ids.has(3) && ids.has(4));
  ids.note(2);  // noted again: now the newest
  ids.note(5);
  EXPECT_TRUE(ids.has(2)) << "a note again keeps an id";
  EXPECT_FALSE(ids.has(3));
  ids.forget(5);
  EXPECT_FALSE(ids.has(5));
  for (uint64_t id = 100; id < 10100; ++id) {  // bounded whatever is noted and forgotten
    ids.note(id);
    if (id % 2) ids.forget(id);
  }
  EXPECT_LE(ids.size(), 3u);
}

// Keyed: the same on every node with the cluster's key, another under another key (a
// player cannot compute which client id gives another player's world id).
TEST(EditIds, APlayersIdIsTheSameUnderOneKeyAndDiffersByPlayerIdAndKey) {
  const EditIds::Key key = EditIds::key_from_secret("world\nsecret");
  EXPECT_EQ(key, EditIds::key_from_secret("world\nsecret"));
  EXPECT_NE(key, EditIds::key_from_secret("world\nother"));
  EXPECT_EQ(EditIds::of_player(key, "alice", 0), 0u);
  EXPECT_EQ(EditIds::of_player(key, "alice", 7), EditIds::of_player(key, "alice", 7));
  EXPECT_NE(EditIds::of_player(key, "alice", 7), EditIds::of_player(key, "bob", 7));
  EXPECT_NE(EditIds::of_player(key, "alice", 7), EditIds::of_player(key, "alice", 8));
  EXPECT_NE(EditIds::of_player(key, "", 1), 0u);
  EXPECT_NE(EditIds::of_player(key, "alice", 7),
            EditIds::of_player(EditIds::random_key(), "alice", 7));
}

std::future<EditResult> submit_async(WorldPipeline& p, world::Edit edit, uint64_t id) {
  auto promise = std::make_shared<std::promise<EditResult>>();
  EditTask task;
  task.edit = std::move(edit);
  task.edit_id = id;
  task.done = [promise](const EditResult& r) { promise->set_value(r); };
  p.submit(std::move(task));
  return promise->get_future();
}

EditResult submit_with_id(WorldPipeline& p, world::Edit edit, uint64_t id) {
  return submit_async(p, std::move(edit), id).get();
}

TEST(EditIds, AResentEditIsAnsweredAndNotAppliedTwice) {
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {1, y / 32 + 1, 1}}).get();
  const world::Edit dig = world::Explosion{{10, float(y), 10}, 4, 1};
  const EditResult first = submit_with_id(p, dig, 42);
  ASSERT_TRUE(first.accepted);
  EXPECT_FALSE(first.already_applied);
  const auto once = test::samples_around(p, 10, y, 10, 6);
  const EditResult again = submit_with_id(p, dig, 42);
  EXPECT_TRUE(again.accepted);
  EXPECT_TRUE(again.already_applied);
  EXPECT_TRUE(again.changed_chunks.empty());
  EXPECT_EQ(test::samples_around(p, 10, y, 10, 6), once) << "the resend was applied again";
  const EditResult other = submit_with_id(p, dig, 43);  // another id: another edit
  EXPECT_TRUE(other.accepted && !other.already_applied);
  EXPECT_NE(test::samples_around(p, 10, y, 10, 6), once);
  p.stop();
}

// A world on a store whose appends can be held and made to fail (tests/gated_store.hpp),
// its surface near (10, y, 10) loaded.
struct GatedWorld {
  explicit GatedWorld(const char* name)
      : tmp(name),
        sqlite(store::open_world_store((tmp / "world").string(), {.seed = 3})),
        store(*sqlite),
        p(PipelineConfig{.seed = 3,
                         .threads = 2,
                         .store = &store,
                         .store_retry = std::chrono::milliseconds(20)}) {
    p.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {1, y / 32 + 1, 1}}).get();
  }
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  test::TempDir tmp;
  std::unique_ptr<store::WorldStore> sqlite;
  test::GatedStore store;
  WorldPipeline p;
};

// An edit undone because its append failed is not remembered: its resend is applied.
TEST(EditIds, AnEditWhoseAppendFailedIsAppliedWhenResent) {
  GatedWorld w("edit_ids_fail");
  const int y = w.y;
  test::GatedStore& store = w.store;
  WorldPipeline& p = w.p;
  const world::Edit dig = world::Explosion{{10, float(y), 10}, 4, 1};
  store.set_failing(true);
  const EditResult failed = submit_with_id(p, dig, 9);
  EXPECT_EQ(failed.reason, world::RefusalReason::kStorageUnavailable);
  store.set_failing(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(40));  // the store's rest
  const EditResult resent = submit_with_id(p, dig, 9);
  EXPECT_TRUE(resent.accepted) << resent.message;
  EXPECT_FALSE(resent.already_applied) << "an undone edit was taken as applied";
  p.stop();
}

// The ids of edits undone behind a failed append (their own batch never tried) are
// forgotten too, and a resend answered "applied already" while its original was still in
// flight is refused with it: once both ids were kept, and a resend was told ACCEPTED for
// an edit the world did not have.
TEST(EditIds, EditsUndoneBehindAFailedAppendAreNotTakenAsApplied) {
  GatedWorld w("edit_ids_behind");
  const int y = w.y;
  test::GatedStore& store = w.store;
  WorldPipeline& p = w.p;
  store.close();
  store.set_failing(true);
  const int entered = store.entered();
  auto first = submit_async(p, world::Explosion{{10, float(y), 10}, 4, 1}, 21);
  ASSERT_TRUE(store.wait_entered(entered + 1));  // its append waits at the gate
  auto behind = submit_async(p, world::Explosion{{14, float(y), 12}, 3, 1}, 22);
  auto resend = submit_async(p, world::Explosion{{10, float(y), 10}, 4, 1}, 21);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // both applied, in flight
  store.open();
  EXPECT_FALSE(first.get().accepted);
  EXPECT_FALSE(behind.get().accepted);
  const EditResult r = resend.get();
  EXPECT_FALSE(r.accepted) << "a resend was ACCEPTED though its original was undone";
  EXPECT_FALSE(r.already_applied);
  store.set_failing(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(40));  // the store's rest
  for (const uint64_t id : {21, 22}) {
    const EditResult again = submit_with_id(
        p, world::Explosion{{id == 21 ? 10.0f : 14.0f, float(y), id == 21 ? 10.0f : 12.0f}, 3, 1},
        id);
    EXPECT_TRUE(again.accepted) << again.message;
    EXPECT_FALSE(again.already_applied) << "edit " << id << " was undone, yet taken as applied";
  }
  p.stop();
}

}  // namespace
}  // namespace vox::pipeline
