// Collapse (server/world/collapse.hpp): which pieces an edit cuts loose, and how far they
// fall.
#include "server/world/collapse.hpp"

#include <gtest/gtest.h>

#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::world {
namespace {

using Pos = std::array<int32_t, 3>;

constexpr Sample kRock{kDensityMax, 3};
constexpr Sample kAirSample{kDensityMin, kAir};

// A world of samples: rock below y = 0, air above, and what a test builds; `emptied`
// collects what carve() turned to air.
struct Scene {
  ChunkMap map;
  std::vector<Pos> emptied;
  Scene() {
    for (int z = -3; z <= 2; ++z)
      for (int x = -3; x <= 2; ++x)
        for (int y = -3; y <= 2; ++y) map.insert({x, y, z}, Chunk(y < 0 ? kRock : kAirSample));
  }
  void fill(Pos lo, Pos hi, Sample s) {
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const ChunkCoord c = chunk_of_voxel(x, y, z);
          map.find(c)->set(floor_mod(x, 32), floor_mod(y, 32), floor_mod(z, 32), s);
        }
  }
  void carve(Pos lo, Pos hi) {
    fill(lo, hi, kAirSample);
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) emptied.push_back({x, y, z});
  }
  SampleAt reader() const {
    return [this](int32_t x, int32_t y, int32_t z) { return map.sample_at(x, y, z); };
  }
  // Two pillars from the ground and a bridge between them, 12 above it.
  void bridge() {
    fill({0, 0, 0}, {3, 15, 3}, kRock);
    fill({20, 0, 0}, {23, 15, 3}, kRock);
    fill({0, 12, 0}, {23, 15, 3}, Sample{kDensityMax, 5});
  }
};

const VoxelBox kSearch{{-8, -8, -8}, {31, 31, 11}};

TEST(Collapse, ABridgeCutAtBothEndsFallsOntoTheGround) {
  Scene s;
  s.bridge();
  s.carve({4, 12, 0}, {5, 15, 3});
  s.carve({18, 12, 0}, {19, 15, 3});
  const auto pieces = find_detached(s.reader(), kSearch, s.emptied, {});
  ASSERT_EQ(pieces.size(), 1u);
  const DetachedPiece& p = pieces[0];
  EXPECT_EQ(p.box.lo, (std::array<int32_t, 3>{6, 12, 0}));
  EXPECT_EQ(p.box.hi, (std::array<int32_t, 3>{17, 15, 3}));
  EXPECT_EQ(p.at.size(), 12u * 4 * 4);
  EXPECT_FALSE(p.removed);
  EXPECT_EQ(p.fall, 12);  // from y = 12 down onto the rock's top sample, y = -1
  ASSERT_EQ(p.holds.size(), 1u);
  EXPECT_EQ(p.holds[0].first, 5);
  EXPECT_DOUBLE_EQ(p.holds[0].second, 12.0 * 4 * 4);
}

TEST(Collapse, AnOverhangStillAttachedAtOneEndStays) {
  Scene s;
  s.bridge();
  s.carve({4, 12, 0}, {5, 15, 3});
  EXPECT_TRUE(find_detached(s.reader(), kSearch, s.emptied, {}).empty());
}

TEST(Collapse, AnIslandThatFloatedBeforeTheEditIsLeftAlone) {
  Scene s;
  s.fill({8, 20, 0}, {11, 23, 3}, kRock);  // stamped in the air: nothing emptied
  EXPECT_TRUE(find_detached(s.reader(), kSearch, s.emptied, {}).empty());
  s.carve({-2, -2, 0}, {0, -1, 1});  // a dig in the ground beside it
  EXPECT_TRUE(find_detached(s.reader(), kSearch, s.emptied, {}).empty());
  // Dug through: both halves float, as the island did before; neither is the edit's doing.
  s.carve({8, 20, 2}, {11, 23, 2});
  EXPECT_TRUE(find_detached(s.reader(), kSearch, s.emptied, {}).empty());
}

TEST(Collapse, ACaveRoofWiderThanTheSearchHoldsAndTheSearchStaysInItsBox) {
  Scene s;
  s.fill({-90, 20, -90}, {60, 24, 60}, kRock);  // a slab wider than the search
  s.carve({10, 20, 2}, {12, 24, 4});            // a hole through it
  size_t reads = 0;
  const SampleAt counting = [&](int32_t x, int32_t y, int32_t z) {
    ++reads;
    return s.map.sample_at(x, y, z);
  };
  EXPECT_TRUE(find_detached(counting, kSearch, s.emptied, {}).empty());
  size_t volume = 1;
  for (int a = 0; a < 3; ++a) volume *= static_cast<size_t>(kSearch.hi[a] - kSearch.lo[a] + 1);
  EXPECT_EQ(reads, volume);  // the box, once; nothing outside it
  // The search box of an edit is bounded whatever the edit.
  const VoxelBox box = collapse_search_box({{-1000, 0, 0}, {1000, 10, 10}}, {});
  EXPECT_EQ(box.hi[0] - box.lo[0] + 1, 80);
  EXPECT_EQ(box.hi[1] - box.lo[1] + 1, 35);  // 11 + 2 * 12
}

TEST(Collapse, APieceWithNothingBelowWithinTheFallIsRemoved) {
  Scene s;
  s.fill({0, 0, 0}, {3, 15, 3}, kRock);
  s.fill({0, 12, 0}, {15, 15, 3}, kRock);
  s.carve({4, 12, 0}, {5, 15, 3});
  CollapseLimits limits;
  limits.max_fall = 8;  // the ground is 12 below
  const auto pieces = find_detached(s.reader(), kSearch, s.emptied, limits);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_TRUE(pieces[0].removed);
}

// The same bridge made and cut by edits (stamps with their smooth 2-voxel boundaries), the
// emptied samples read off the world before and after the cuts.
TEST(Collapse, ABridgeOfStampsCutByStampsFalls) {
  Scene s;
  const auto stamp = [&](Vec3 lo, Vec3 hi, bool solid) {
    Stamp st;
    st.shape = Stamp::Shape::kBox;
    st.min = lo, st.max = hi, st.solid = solid, st.material = 5;
    const Edit e = st;
    for (const ChunkCoord& c : chunks_overlapping(touched_box(e)))
      apply_edit(e, c, *s.map.find(c), nullptr);
  };
  stamp({0, -2, 0}, {4, 16, 4}, true);
  stamp({24, -2, 0}, {28, 16, 4}, true);
  stamp({0, 12, 0}, {28, 16, 4}, true);
  ChunkMap before;
  for (const auto& [c, chunk] : s.map) before.insert(c, chunk);
  stamp({6, 10, -2}, {8, 18, 6}, false);
  stamp({20, 10, -2}, {22, 18, 6}, false);
  for (int z = -8; z <= 11; ++z)
    for (int y = -8; y <= 31; ++y)
      for (int x = -8; x <= 31; ++x)
        if (is_solid(before.sample_at(x, y, z).density) &&
            !is_solid(s.map.sample_at(x, y, z).density))
          s.emptied.push_back({x, y, z});
  ASSERT_FALSE(s.emptied.empty());
  const auto pieces = find_detached(s.reader(), kSearch, s.emptied, {});
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_GE(pieces[0].box.lo[0], 8);
  EXPECT_LE(pieces[0].box.hi[0], 20);
  EXPECT_GE(pieces[0].box.lo[1], 11);
  EXPECT_GT(pieces[0].fall, 8);
  EXPECT_FALSE(pieces[0].removed);
}

}  // namespace
}  // namespace vox::world
