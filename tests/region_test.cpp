// Protected regions: which edits they hold back (pure), and the pipeline applying them —
// samples inside a region are bit-identical after every kind of edit by a non-owner from
// outside, at its corners and faces and across chunk borders; a stamp wholly inside is
// refused; owners and admins edit inside; regions and clipped edits survive a restart
// and replay bit for bit.
#include "server/world/region.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <future>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/pipeline_test_util.hpp"
#include "tests/postgres_server.hpp"
#include "tests/temp_dir.hpp"

namespace vox::pipeline {
namespace {

using world::VoxelBox;

world::Region region(VoxelBox box, uint8_t flags, std::vector<std::string> owners = {}) {
  world::Region r;
  r.name = "test";
  r.box = box;
  r.flags = flags;
  r.owners = std::move(owners);
  return r;
}

TEST(ProtectedRegion, ProtectionDependsOnFlagsOwnersAndWhereTheEditLies) {
  std::vector<world::Region> regions{
      region({{0, 0, 0}, {9, 9, 9}}, world::kProtectBuild, {"alice"}),
      region({{20, 0, 0}, {29, 9, 9}}, world::kProtectExplode)};
  regions[0].id = 1, regions[1].id = 2;
  const world::Edit brush = world::Brush{{10, 5, 5}, 3};  // reaches into region 1 only
  auto p = world::protection_for(regions, brush, "mallory");
  ASSERT_EQ(p.regions, std::vector<uint64_t>{1});
  EXPECT_EQ(p.keep[0].lo, (std::array<int32_t, 3>{7, 2, 2})) << "clipped to the touched box";
  EXPECT_EQ(p.keep[0].hi, (std::array<int32_t, 3>{9, 8, 8}));
  EXPECT_TRUE(world::protection_for(regions, brush, "alice").keep.empty()) << "an owner";
  EXPECT_FALSE(world::protection_for(regions, brush, "").keep.empty()) << "no id owns nothing";
  const world::Edit boom = world::Explosion{{10, 5, 5}, 3, 1};
  EXPECT_TRUE(world::protection_for(regions, boom, "mallory").keep.empty())
      << "region 1 protects against building only";
  const world::Edit inside = world::Explosion{{25, 5, 5}, 2, 1};
  EXPECT_EQ(world::protection_for(regions, inside, "mallory").forbidden_by, 2u);
  world::Stamp stamp;
  stamp.min = {2, 2, 2}, stamp.max = {7, 7, 7};  // its 2-voxel margin reaches outside
  EXPECT_EQ(world::protection_for(regions, stamp, "mallory").forbidden_by, 1u);
  stamp.max = {12, 7, 7};
  EXPECT_FALSE(world::protection_for(regions, stamp, "mallory").forbidden_by);
  EXPECT_EQ(world::protection_for(regions, stamp, "mallory").regions, std::vector<uint64_t>{1});
}

TEST(ProtectedRegion, InvalidRegionsAreRefusedWithAReason) {
  const world::EditLimits limits;
  const world::RegionLimits rl;
  EXPECT_FALSE(world::validate_region(region({{0, 0, 0}, {1, 1, 1}}, 3, {"a"}), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{2, 0, 0}, {1, 1, 1}}, 3), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{0, 0, 0}, {1, 1, 1}}, 0), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{0, 0, 0}, {1, 1, 1}}, 4), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{0, 0, 0}, {1, 1, 1}}, 3, {"a\nb"}), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{0, 0, 0}, {1, 1, 1}}, 3, {""}), limits, rl));
  EXPECT_TRUE(world::validate_region(region({{0, 0, 0}, {1, 1 << 20, 1}}, 3), limits, rl))
      << "outside the world";
  auto many = region({{0, 0, 0}, {1, 1, 1}}, 3, std::vector<std::string>(33, "x"));
  EXPECT_TRUE(world::validate_region(many, limits, rl));
}

EditResult submit_as(WorldPipeline& p, world::Edit e, const std::string& author,
                     bool admin = false) {
  std::promise<EditResult> done;
  auto f = done.get_future();
  p.submit(
      std::move(e), [&done](const EditResult& r) { done.set_value(r); }, 0, author, admin);
  return f.get();
}

RegionOutcome change(WorldPipeline& p, RegionTask task) {
  std::promise<RegionOutcome> done;
  auto f = done.get_future();
  task.done = [&done](const RegionOutcome& r) { done.set_value(r); };
  p.change_regions(std::move(task));
  return f.get();
}

RegionOutcome add(WorldPipeline& p, world::Region r) {
  return change(p, RegionTask{std::move(r), 0, "admin", {}});
}

std::vector<world::Sample> samples_in(WorldPipeline& p, const VoxelBox& b) {
  std::vector<world::Sample> out;
  p.inspect([&](const world::ChunkMap& map) {
    for (int z = b.lo[2]; z <= b.hi[2]; ++z)
      for (int y = b.lo[1]; y <= b.hi[1]; ++y)
        for (int x = b.lo[0]; x <= b.hi[0]; ++x) out.push_back(map.sample_at(x, y, z));
  });
  return out;
}

VoxelBox grown(VoxelBox b, int by) {
  for (int a = 0; a < 3; ++a) b.lo[a] -= by, b.hi[a] += by;
  return b;
}

// A box across chunk borders (x and z cross 32, y around the surface), and explosions
// from outside at each corner and face: nothing inside changes, the outside does.
struct ProtectedWorld {
  ProtectedWorld() : y(static_cast<int>(world::TerrainGenerator(3).height_at(32, 32))) {
    box = {{24, y - 10, 24}, {40, y + 6, 40}};
    p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {1, y / 32 + 1, 1}}).get();
    const RegionOutcome out = add(p, region(box, world::kRegionFlagsKnown, {"alice"}));
    EXPECT_EQ(out.status, RegionOutcome::Status::kOk) << out.message;
    id = out.region.id;
  }
  WorldPipeline p{PipelineConfig{.seed = 3, .threads = 2}};
  int y;
  VoxelBox box;
  uint64_t id = 0;
};

TEST(ProtectedRegion, SamplesInsideAreBitIdenticalAfterExplosionsFromOutside) {
  ProtectedWorld w;
  const auto inside = samples_in(w.p, w.box);
  const auto around = samples_in(w.p, grown(w.box, 6));
  const VoxelBox& b = w.box;
  std::vector<world::Vec3> centres;
  for (int corner = 0; corner < 8; ++corner) {  // just outside each corner
    centres.push_back({static_cast<float>(corner & 1 ? b.hi[0] + 2 : b.lo[0] - 2),
                       static_cast<float>(corner & 2 ? b.hi[1] + 2 : b.lo[1] - 2),
                       static_cast<float>(corner & 4 ? b.hi[2] + 2 : b.lo[2] - 2)});
  }
  const float mid[3] = {0.5f * (b.lo[0] + b.hi[0]), 0.5f * (b.lo[1] + b.hi[1]),
                        0.5f * (b.lo[2] + b.hi[2])};
  for (int a = 0; a < 3; ++a) {  // just outside each face
    for (const int side : {b.lo[a] - 3, b.hi[a] + 3}) {
      float c[3] = {mid[0], mid[1], mid[2]};
      c[a] = static_cast<float>(side);
      centres.push_back({c[0], c[1], c[2]});
    }
  }
  for (const world::Vec3& c : centres) {
    const EditResult r = submit_as(w.p, world::Explosion{c, 9, 3}, "mallory");
    ASSERT_TRUE(r.accepted) << r.message;
    EXPECT_EQ(r.clipped_by, std::vector<uint64_t>{w.id});
  }
  EXPECT_EQ(samples_in(w.p, w.box), inside) << "a sample inside the region changed";
  EXPECT_NE(samples_in(w.p, grown(w.box, 6)), around) << "nothing outside changed";
  // Its owner, and an admin, change it.
  ASSERT_TRUE(submit_as(w.p, world::Explosion{{mid[0], mid[1], mid[2]}, 6, 3}, "alice").accepted);
  const auto owned = samples_in(w.p, w.box);
  EXPECT_NE(owned, inside);
  const EditResult admin = submit_as(w.p, world::Explosion{{30, mid[1], 30}, 6, 3}, "root", true);
  ASSERT_TRUE(admin.accepted);
  EXPECT_TRUE(admin.clipped_by.empty());
  EXPECT_NE(samples_in(w.p, w.box), owned);
}

TEST(ProtectedRegion, EveryEditKindIsClippedAndAStampWhollyInsideIsRefused) {
  ProtectedWorld w;
  const auto inside = samples_in(w.p, w.box);
  const float yf = static_cast<float>(w.y);
  world::Stamp box_stamp;  // half in, half out, across the x = 24 face
  box_stamp.min = {18, yf - 4, 28}, box_stamp.max = {30, yf + 4, 36};
  world::Stamp sphere;
  sphere.shape = world::Stamp::Shape::kSphere;
  sphere.center = {41, yf, 41}, sphere.radius = 6, sphere.solid = false;
  const std::vector<world::Edit> edits{world::Brush{{23, yf, 32}, 6, 2, false, world::Material{5}},
                                       world::Brush{{41, yf, 32}, 6, 2, true, std::nullopt},
                                       world::Smooth{{32, yf, 23}, 6, 1},
                                       world::Paint{{32, yf - 1, 41}, 6, 9},
                                       box_stamp,
                                       sphere};
  for (const world::Edit& e : edits) {
    const auto around = samples_in(w.p, grown(w.box, 7));
    const EditResult r = submit_as(w.p, e, "mallory");
    ASSERT_TRUE(r.accepted) << r.message;
    EXPECT_EQ(r.clipped_by, std::vector<uint64_t>{w.id}) << "edit kind " << e.index();
    EXPECT_EQ(samples_in(w.p, w.box), inside) << "edit kind " << e.index() << " reached inside";
    EXPECT_NE(samples_in(w.p, grown(w.box, 7)), around)
        << "edit kind " << e.index() << " changed nothing outside";
  }
  world::Stamp within;
  within.min = {28, yf - 4, 28}, within.max = {36, yf + 2, 36};
  const EditResult refused = submit_as(w.p, within, "mallory");
  EXPECT_FALSE(refused.accepted);
  EXPECT_EQ(refused.reason, world::RefusalReason::kForbidden);
  EXPECT_NE(refused.message.find(std::to_string(w.id)), std::string::npos) << refused.message;
  // A region that protects against explosions only lets building in.
  const RegionOutcome removed = change(w.p, RegionTask{std::nullopt, w.id, "admin", {}});
  ASSERT_EQ(removed.status, RegionOutcome::Status::kOk);
  EXPECT_EQ(removed.region.id, w.id);
  EXPECT_EQ(change(w.p, RegionTask{std::nullopt, w.id, "admin", {}}).status,
            RegionOutcome::Status::kNotFound);
  ASSERT_EQ(add(w.p, region(w.box, world::kProtectExplode)).status, RegionOutcome::Status::kOk);
  EXPECT_TRUE(submit_as(w.p, within, "mallory").accepted);
  EXPECT_NE(samples_in(w.p, w.box), inside);
  EXPECT_EQ(w.p.regions()->size(), 1u);
  EXPECT_EQ(add(w.p, region({{0, 0, 0}, {-1, 0, 0}}, 3)).status, RegionOutcome::Status::kBadValue);
}

// The regions are in the store; the log keeps what each edit was clipped by, so the
// edit replays bit for bit on a world that no longer has (or never had) the region; after
// a restart the region still holds.
TEST(ProtectedRegion, RegionsAndClippedEditsSurviveARestartAndReplayBitForBit) {
  const test::TempDir tmp("region_restart");
  const auto dir = tmp / "world";
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(32, 32));
  const VoxelBox box{{24, y - 10, 24}, {40, y + 6, 40}};
  const world::Edit boom = world::Explosion{{22, static_cast<float>(y), 22}, 9, 3};
  const mesh::ChunkBox loaded{{0, (y - 16) / 32 - 1, 0}, {1, (y + 16) / 32 + 1, 1}};
  std::vector<world::Sample> after;
  {
    auto store = store::open_world_store(dir.string(), {.seed = 3});
    WorldPipeline p(PipelineConfig{.seed = 3,
                                   .threads = 2,
                                   .store = store.get(),
                                   .checkpoint = {.interval = std::chrono::hours(1)}});
    p.load(loaded).get();
    ASSERT_EQ(add(p, region(box, world::kRegionFlagsKnown, {"alice"})).status,
              RegionOutcome::Status::kOk);
    ASSERT_TRUE(submit_as(p, boom, "mallory").accepted);
    after = samples_in(p, grown(box, 4));
    std::vector<store::LoggedEdit> log;
    store->for_each_edit(0, [&](const store::LoggedEdit& e) {
      log.push_back(e);
      return true;
    });
    ASSERT_EQ(log.size(), 1u);
    EXPECT_EQ(log[0].author, "mallory");
    ASSERT_EQ(log[0].keep.size(), 1u);
    // Replayed outside the pipeline, without any region: the same samples.
    world::ChunkMap map;
    const world::TerrainGenerator gen(3);
    world::replay_edit(map, gen, log[0].edit, log[0].keep);
    std::vector<world::Sample> replayed;
    const VoxelBox g = grown(box, 4);
    for (int z = g.lo[2]; z <= g.hi[2]; ++z)
      for (int yy = g.lo[1]; yy <= g.hi[1]; ++yy)
        for (int x = g.lo[0]; x <= g.hi[0]; ++x) {
          if (!map.find(world::chunk_of_voxel(x, yy, z)))
            map.insert(world::chunk_of_voxel(x, yy, z),
                       gen.generate(world::chunk_of_voxel(x, yy, z)));
          replayed.push_back(map.sample_at(x, yy, z));
        }
    EXPECT_EQ(replayed, after);
  }
  auto store = store::open_world_store(dir.string(), {.seed = 3});
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = store.get()});
  p.load(loaded).get();
  ASSERT_EQ(p.regions()->size(), 1u);
  EXPECT_EQ(p.regions()->front().owners, std::vector<std::string>{"alice"});
  EXPECT_EQ(samples_in(p, grown(box, 4)), after);
  const auto inside = samples_in(p, box);
  const EditResult again =
      submit_as(p, world::Explosion{{42, static_cast<float>(y), 42}, 9, 3}, "mallory");
  ASSERT_TRUE(again.accepted);
  EXPECT_FALSE(again.clipped_by.empty());
  EXPECT_EQ(samples_in(p, box), inside);
  p.stop();
}

// With no checkpoint since (the store went away at stop, as in a crash), the next start
// replays the clipped edit from the log: the region's samples are still as they were, in
// PostgreSQL as in SQLite, and the region itself was read back.
TEST(ProtectedRegion, AClippedEditReplayedFromTheLogLeavesTheRegionAsItWas) {
  test::PostgresServer server;
  auto store = store::open_world_store(server.create_database("regions"), {.seed = 3});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(32, 32));
  const VoxelBox box{{24, y - 10, 24}, {40, y + 6, 40}};
  const mesh::ChunkBox loaded{{0, (y - 16) / 32 - 1, 0}, {1, (y + 16) / 32 + 1, 1}};
  const PipelineConfig config{.seed = 3,
                              .threads = 2,
                              .store = store.get(),
                              .checkpoint = {.interval = std::chrono::hours(1)}};
  std::vector<world::Sample> inside, after;
  {
    WorldPipeline p(config);
    p.load(loaded).get();
    inside = samples_in(p, box);
    ASSERT_EQ(add(p, region(box, world::kProtectExplode)).status, RegionOutcome::Status::kOk);
    for (const float x : {22.0f, 42.0f})
      ASSERT_FALSE(submit_as(p, world::Explosion{{x, static_cast<float>(y), x}, 9, 3}, "m")
                       .clipped_by.empty());
    after = samples_in(p, grown(box, 4));
    server.stop();
    p.stop();
    EXPECT_EQ(p.stats().checkpoint_failures, 1u);
  }
  server.start();
  WorldPipeline p(config);
  p.load(loaded).get();
  EXPECT_EQ(p.regions()->size(), 1u);
  EXPECT_EQ(samples_in(p, grown(box, 4)), after);
  EXPECT_EQ(samples_in(p, box), inside);
}

}  // namespace
}  // namespace vox::pipeline
