#include "server/world/edit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "server/world/edit_apply.hpp"
#include "server/world/zone.hpp"

namespace vox::world {
namespace {

RefusalReason reason_of(const Edit& e) {
  const auto r = validate(e, EditLimits{});
  return r ? r->reason : RefusalReason::kNone;
}

TEST(EditValidation, RefusesEachBadValueWithItsReason) {
  const float nan = std::numeric_limits<float>::quiet_NaN(),
              inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 4, 0.5f}), RefusalReason::kNone);
  EXPECT_EQ(reason_of(Brush{{nan, 0, 0}, 4, 0.5f}), RefusalReason::kNotFinite);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, inf, 0.5f}), RefusalReason::kNotFinite);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 4, nan}), RefusalReason::kNotFinite);
  EXPECT_EQ(reason_of(Explosion{{0, inf, 0}, 4, 1}), RefusalReason::kNotFinite);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 0, 0.5f}), RefusalReason::kBadRadius);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, -3, 0.5f}), RefusalReason::kBadRadius);
  EXPECT_EQ(reason_of(Explosion{{0, 0, 0}, 33, 1}), RefusalReason::kBadRadius);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 4, 0}), RefusalReason::kBadStrength);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 4, 4.5f}), RefusalReason::kBadStrength);
  EXPECT_EQ(reason_of(Explosion{{0, 0, 0}, 4, -1}), RefusalReason::kBadStrength);
  EXPECT_EQ(reason_of(Smooth{{0, 0, 0}, 4, 2}), RefusalReason::kBadStrength);
  EXPECT_EQ(reason_of(Brush{{2e6f, 0, 0}, 4, 0.5f}), RefusalReason::kOutOfBounds);
  EXPECT_EQ(reason_of(Brush{{0, 4094, 0}, 4, 0.5f}), RefusalReason::kOutOfBounds);
  EXPECT_EQ(reason_of(Explosion{{0, -1e30f, 0}, 4, 1}), RefusalReason::kOutOfBounds);
  EXPECT_EQ(reason_of(Paint{{0, 0, 0}, 4, kAir}), RefusalReason::kBadMaterial);
  EXPECT_EQ(reason_of(Brush{{0, 0, 0}, 4, 0.5f, false, kAir}), RefusalReason::kBadMaterial);
  Stamp big;
  big.min = {0, 0, 0};
  big.max = {100, 1, 1};
  EXPECT_EQ(reason_of(big), RefusalReason::kBadRadius);
  Stamp inverted;
  inverted.min = {5, 5, 5};
  inverted.max = {1, 6, 6};
  EXPECT_EQ(reason_of(inverted), RefusalReason::kBadRadius);
  Stamp ok;
  ok.min = {0, 0, 0};
  ok.max = {4, 4, 4};
  EXPECT_EQ(reason_of(ok), RefusalReason::kNone);
  const auto refusal = validate(Brush{{nan, 0, 0}, 4, 0.5f}, EditLimits{});
  ASSERT_TRUE(refusal);
  EXPECT_NE(refusal->message.find("not finite"), std::string::npos);
}

std::vector<ChunkCoord> dirty_for(int lo, int hi) {
  ChangedBox b;
  b.add(lo, lo, lo);
  b.add(hi, hi, hi);
  std::vector<ChunkCoord> out;
  append_dirty_chunks({0, 0, 0}, b, out);
  return out;
}

TEST(EditDirtyTracking, OnlyChunksWhoseMeshesReadTheChangedSamples) {
  EXPECT_EQ(dirty_for(10, 20).size(), 1u);  // interior: the chunk itself
  EXPECT_EQ(dirty_for(2, 30).size(), 1u);   // samples 2..30 are read by no neighbour
  EXPECT_EQ(dirty_for(1, 20).size(), 8u);   // sample 1 is in the -1 neighbours' gradient apron
  EXPECT_EQ(dirty_for(10, 31).size(), 8u);  // sample 31 is in the +1 neighbours' apron
  EXPECT_EQ(dirty_for(0, 31).size(), 27u);
  ChangedBox face;  // a change touching only the -x face region
  face.add(0, 10, 10);
  face.add(5, 12, 12);
  std::vector<ChunkCoord> out;
  append_dirty_chunks({3, 4, 5}, face, out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0], (ChunkCoord{2, 4, 5}));
  EXPECT_EQ(out[1], (ChunkCoord{3, 4, 5}));
}

Chunk half_solid() {  // solid below y = 16
  Chunk c;
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) c.set(x, y, z, y < 16 ? Sample{kDensityMax, 3} : Sample{});
  return c;
}

TEST(EditApply, EachEditTypeChangesWhatItShould) {
  {
    Chunk c = half_solid();
    const auto changed =
        apply_edit(Brush{{16, 20, 16}, 3, 1.5f, false, Material{7}}, {0, 0, 0}, c, nullptr);
    EXPECT_TRUE(changed.changed);
    EXPECT_TRUE(is_solid(c.at(16, 20, 16).density));
    EXPECT_EQ(c.at(16, 20, 16).material, 7);
    EXPECT_FALSE(is_solid(c.at(16, 23, 16).density)) << "the falloff reaches 0 at the radius";
  }
  {
    Chunk c = half_solid();
    apply_edit(Explosion{{16, 15, 16}, 4, 3}, {0, 0, 0}, c, nullptr);
    EXPECT_FALSE(is_solid(c.at(16, 15, 16).density));
    EXPECT_EQ(c.at(16, 15, 16).material, kAir);
    EXPECT_TRUE(is_solid(c.at(16, 10, 16).density));
  }
  {
    Chunk c = half_solid();
    const Chunk before = c;
    apply_edit(Paint{{16, 15, 16}, 3, 9}, {0, 0, 0}, c, nullptr);
    EXPECT_EQ(c.at(16, 15, 16), (Sample{kDensityMax, 9}));
    EXPECT_EQ(c.at(16, 17, 16), Sample{}) << "paint leaves air alone";
    for (int i = 0; i < kChunkVolume; ++i) EXPECT_EQ(c.at(i).density, before.at(i).density);
  }
  {
    Chunk c = half_solid();
    Stamp s;
    s.min = {4, 20, 4};
    s.max = {8, 24, 8};
    s.material = 5;
    apply_edit(s, {0, 0, 0}, c, nullptr);
    EXPECT_EQ(c.at(6, 22, 6), (Sample{kDensityMax, 5}));
    EXPECT_FALSE(is_solid(c.at(12, 22, 12).density));
    s.solid = false;
    s.min = {4, 8, 4};
    s.max = {8, 12, 8};
    apply_edit(s, {0, 0, 0}, c, nullptr);
    EXPECT_EQ(c.at(6, 10, 6), Sample{});
  }
  {
    ChunkMap map;
    map.insert({0, 0, 0}, half_solid());
    Chunk& c = *map.find({0, 0, 0});
    c.set(16, 20, 16, {kDensityMax, 3});  // a lone solid spike in the air
    const Smooth smooth{{16, 20, 16}, 3, 1.0f};
    const SampleSnapshot snap = take_snapshot(map, smooth_read_box(smooth));
    apply_edit(smooth, {0, 0, 0}, c, &snap);
    EXPECT_FALSE(is_solid(c.at(16, 20, 16).density)) << "smoothing removes the spike";
  }
}

// In a cluster world a smooth reads, around each sample, only its own zone's samples: so
// applying it whole equals applying each zone's part alone (the other zones' samples
// kept), in any order, and a part's result does not depend on the other zones' samples.
// That is what lets each zone replay its part from its own log.
TEST(EditApply, ASmoothReadingWithinZonesEqualsItsZonesPartsAppliedAlone) {
  constexpr int kZone = 1;  // zones of one chunk: chunks (0,0,0) and (1,0,0) differ
  const auto world_with = [](int salt) {
    ChunkMap map;
    for (const int cx : {0, 1}) {
      Chunk c = half_solid();
      for (int z = 10; z < 22; ++z)
        for (int y = 14; y < 26; ++y)
          for (int x = 0; x < kChunkSize; ++x) {
            const int h = (x * 7 + y * 13 + z * 5 + cx * 11 + (cx == 1 ? salt : 0)) % 23;
            c.set(x, y, z, {static_cast<int8_t>(h * 10 - 110), static_cast<Material>(1 + h % 4)});
          }
      map.insert({cx, 0, 0}, std::move(c));
    }
    return map;
  };
  const Smooth smooth{{32.0f, 20.0f, 16.0f}, 5.0f, 0.9f};  // across the border at x = 32
  const VoxelBox touched = touched_box(Edit{smooth});
  const auto apply = [&](ChunkMap& map, std::span<const VoxelBox> keep) {
    SampleSnapshot snap = take_snapshot(map, smooth_read_box(smooth));
    snap.zone_chunks = kZone;
    for (const int cx : {0, 1}) apply_edit(smooth, {cx, 0, 0}, *map.find({cx, 0, 0}), &snap, keep);
  };
  const auto outside = [&](ZoneId z) { return outside_zone(touched, z, kZone); };
  ChunkMap whole = world_with(0);
  apply(whole, {});
  ChunkMap parts = world_with(0), reversed = world_with(0);
  apply(parts, outside({0, 0}));
  apply(parts, outside({1, 0}));
  apply(reversed, outside({1, 0}));
  apply(reversed, outside({0, 0}));
  ChunkMap other = world_with(5);  // zone 1's samples differ
  apply(other, outside({0, 0}));
  for (int z = 0; z < kChunkSize; ++z)
    for (int y = 0; y < kChunkSize; ++y)
      for (int x = 0; x < kChunkSize; ++x)
        for (const int cx : {0, 1}) {
          const Sample w = whole.find({cx, 0, 0})->at(x, y, z);
          ASSERT_EQ(parts.find({cx, 0, 0})->at(x, y, z), w)
              << cx << " " << x << " " << y << " " << z;
          ASSERT_EQ(reversed.find({cx, 0, 0})->at(x, y, z), w);
          if (cx == 0) ASSERT_EQ(other.find({0, 0, 0})->at(x, y, z), w) << "zone 0 read zone 1";
        }
  ChunkMap changed = world_with(0);
  EXPECT_NE(changed.find({0, 0, 0})->at(31, 20, 16), whole.find({0, 0, 0})->at(31, 20, 16))
      << "the smooth changed nothing at the border";
}

TEST(EditApply, NoChangeReportsNothing) {
  Chunk rock(Sample{kDensityMax, 3});
  EXPECT_FALSE(apply_edit(Brush{{16, 16, 16}, 4, 1.0f}, {0, 0, 0}, rock, nullptr).changed);
  EXPECT_TRUE(rock.is_uniform());
  Chunk sky;
  EXPECT_FALSE(apply_edit(Explosion{{16, 16, 16}, 8, 2}, {0, 0, 0}, sky, nullptr).changed);
  EXPECT_TRUE(sky.is_uniform());
}

// voxeld refuses an --edit-burst below the largest edit's cost; it once took (2r + 5)^3,
// which a stamp off the integer grid exceeds, so such an edit was refused for ever.
TEST(EditValidation, MaxTouchedSamplesCoversTheLargestEditsOffTheGrid) {
  const EditLimits limits;
  Stamp box;
  box.min = {0.5f, -7.25f, 100.5f};
  box.max = {box.min.x + 64, box.min.y + 64, box.min.z + 64};
  Stamp ball;
  ball.shape = Stamp::Shape::kSphere;
  ball.center = {0.5f, 0.5f, -0.5f};
  ball.radius = limits.max_radius;
  for (const Edit& e : {Edit{box}, Edit{ball}}) {
    ASSERT_FALSE(validate(e, limits));
    const VoxelBox b = touched_box(e);
    double samples = 1;
    for (int a = 0; a < 3; ++a) samples *= b.hi[a] - b.lo[a] + 1;
    EXPECT_EQ(samples, 70.0 * 70 * 70);
    EXPECT_LE(samples, max_touched_samples(limits));
  }
}

}  // namespace
}  // namespace vox::world
