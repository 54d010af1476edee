// Online rollbacks (pipeline/rollbacks.hpp) on a running pipeline with a durable world:
// players A and B edit the same chunks in turn; rolling B back leaves exactly the world of
// A's edits alone, byte for byte, published and durable (a restart replays the record, or
// reads the checkpoint), and undoing the rollback brings B's edits back; edits reaching a
// frozen chunk are refused SERVER_BUSY until it thaws.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <map>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/replay_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::pipeline {
namespace {

using world::ChunkCoord;
using namespace std::chrono_literals;

constexpr uint64_t kSeed = 5;

struct Turn {
  std::string who;
  world::Edit edit;
};

std::vector<Turn> turns(float y) {
  return {
      {"A", world::Brush{{20, y, 16}, 6, 0.9f, false, 3}},
      {"B", world::Explosion{{30, y, 16}, 7, 1}},
      {"A", world::Paint{{28, y, 16}, 5, 4}},
      {"B",
       world::Stamp{world::Stamp::Shape::kBox, {34, y - 4, 10}, {40, y + 6, 20}, {}, 0, true, 5}},
      {"A", world::Smooth{{33, y, 16}, 6, 0.7f}},
      {"B", world::Brush{{36, y, 20}, 4, 0.5f, true, 0}}};
}

std::map<ChunkCoord, world::Chunk> replayed(const std::vector<Turn>& edits,
                                            const std::string& skip) {
  return test::replayed_without(edits, skip, world::TerrainGenerator(kSeed));
}

// The pipeline's chunks against `want`: every one resident and equal.
void expect_world(WorldPipeline& p, const std::map<ChunkCoord, world::Chunk>& want) {
  size_t equal = 0;
  p.inspect([&](const world::ChunkMap& map) {
    for (const auto& [c, chunk] : want) {
      const world::Chunk* got = map.find(c);
      ASSERT_NE(got, nullptr) << c.x << "," << c.y << "," << c.z;
      EXPECT_TRUE(*got == chunk) << "chunk " << c.x << "," << c.y << "," << c.z;
      equal += *got == chunk ? 1 : 0;
    }
  });
  EXPECT_EQ(equal, want.size());
}

RollbackReport roll_back(WorldPipeline& p, store::RollbackQuery q, bool dry_run = false) {
  std::promise<RollbackReport> report;
  p.rollback({.query = std::move(q),
              .dry_run = dry_run,
              .by = "admin",
              .done = [&](const RollbackReport& r) { report.set_value(r); }});
  return report.get_future().get();
}

struct World {
  explicit World(const std::filesystem::path& dir)
      : store(store::open_world_store(dir.string(), {.seed = kSeed})),
        checkpoints(store::open_world_store(dir.string(), {.seed = kSeed, .record_start = false})),
        history(store::open_world_store(dir.string(), {.seed = kSeed, .record_start = false})) {}
  PipelineConfig config() {
    return PipelineConfig{.seed = kSeed,
                          .threads = 2,
                          .store = store.get(),
                          .checkpoint_store = checkpoints.get(),
                          .history_store = history.get(),
                          .history = {.window = std::chrono::hours(24 * 7)}};
  }
  std::unique_ptr<store::WorldStore> store, checkpoints, history;
};

TEST(Rollback, RollingBackBOnARunningServerLeavesTheWorldOfAAloneAndSurvivesARestart) {
  const test::TempDir tmp("rollback_ab");
  const float y = static_cast<float>(world::TerrainGenerator(kSeed).height_at(16, 16));
  const std::vector<Turn> edits = turns(y);
  uint64_t record = 0;
  {
    World w(tmp / "world");
    WorldPipeline p(w.config());
    p.load(
         mesh::ChunkBox{{0, static_cast<int>(y) / 32 - 1, 0}, {1, static_cast<int>(y) / 32 + 1, 0}})
        .get();
    for (const Turn& t : edits) {
      std::promise<EditResult> r;
      p.submit(
          t.edit, [&](const EditResult& x) { r.set_value(x); }, 0, t.who);
      ASSERT_TRUE(r.get_future().get().accepted);
    }
    const RollbackReport plan = roll_back(p, {.player = "B"}, true);
    EXPECT_EQ(plan.status, RollbackReport::Status::kOk) << plan.message;
    EXPECT_EQ(plan.edits, 3u);
    EXPECT_EQ(plan.record, 0u);
    expect_world(p, replayed(edits, ""));  // a dry run changes nothing

    const uint64_t published = p.stats().meshes_published;
    const RollbackReport done = roll_back(p, {.player = "B"});
    ASSERT_EQ(done.status, RollbackReport::Status::kOk) << done.message;
    EXPECT_EQ(done.edits, 3u);
    EXPECT_EQ(done.chunks, plan.chunks);
    EXPECT_EQ(done.record, edits.size() + 1);
    record = done.record;
    expect_world(p, replayed(edits, "B"));
    EXPECT_GT(p.stats().meshes_published, published) << "the clients saw nothing of it";
    // Nothing of B's is left to roll back; the chunks thawed (edits go in again).
    EXPECT_EQ(roll_back(p, {.player = "B"}).edits, 0u);
    std::promise<EditResult> after;
    p.submit(world::Paint{{30, y, 16}, 1, 2}, [&](const EditResult& x) { after.set_value(x); });
    const EditResult r = after.get_future().get();
    EXPECT_TRUE(r.accepted) << r.message;
  }
  {  // A restart (from the final checkpoint; the replay of a logged record is the store
     // tests'): A's world and the paint after, and the rollback can be undone.
    World w(tmp / "world");
    WorldPipeline p(w.config());
    std::map<ChunkCoord, world::Chunk> want = replayed(edits, "B");
    // The paint went in after: onto A's world.
    world::ChunkMap map;
    for (auto& [c, chunk] : want) map.insert(c, chunk);
    const world::TerrainGenerator gen(kSeed);
    world::replay_edit(map, gen, world::Paint{{30, y, 16}, 1, 2});
    for (auto& [c, chunk] : want) chunk = *map.find(c);
    p.load(
         mesh::ChunkBox{{0, static_cast<int>(y) / 32 - 1, 0}, {1, static_cast<int>(y) / 32 + 1, 0}})
        .get();
    expect_world(p, want);
    // Undoing the rollback brings B's edits back.
    const RollbackReport back = roll_back(p, {.undo_record = record});
    ASSERT_EQ(back.status, RollbackReport::Status::kOk) << back.message;
    EXPECT_EQ(back.edits, 3u);
  }
}

TEST(Rollback, EditsReachingAFrozenChunkAreRefusedBusyUntilItThaws) {
  const test::TempDir tmp("rollback_frozen");
  World w(tmp / "world");
  WorldPipeline p(w.config());
  const float y = static_cast<float>(world::TerrainGenerator(kSeed).height_at(16, 16));
  const ChunkCoord c{0, static_cast<int32_t>(y) / 32, 0};
  const auto step = [&](RollbackTask::Kind kind) {
    std::promise<uint64_t> done;
    RollbackTask t;
    t.kind = kind;
    t.coords = {c};
    t.done = [&](bool, uint64_t seq) { done.set_value(seq); };
    p.submit_rollback(std::move(t));
    return done.get_future().get();
  };
  EXPECT_EQ(step(RollbackTask::Kind::kFreeze), 0u);
  const EditResult refused = p.submit(world::Explosion{{16, y, 16}, 4, 1}).get();
  EXPECT_FALSE(refused.accepted);
  EXPECT_EQ(refused.reason, world::RefusalReason::kServerBusy);
  // A smooth next door reads the frozen chunk: refused too; an edit elsewhere goes in.
  EXPECT_FALSE(p.submit(world::Smooth{{33, y, 16}, 4, 0.5f}).get().accepted);
  EXPECT_TRUE(p.submit(world::Explosion{{80, y, 16}, 4, 1}).get().accepted);
  step(RollbackTask::Kind::kThaw);
  EXPECT_TRUE(p.submit(world::Explosion{{16, y, 16}, 4, 1}).get().accepted);
  EXPECT_EQ(step(RollbackTask::Kind::kFreeze), 2u) << "the last edit logged before the freeze";
  step(RollbackTask::Kind::kThaw);
}

}  // namespace
}  // namespace vox::pipeline
