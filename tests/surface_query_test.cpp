// Queries about the samples (mesh/surface_query.hpp) against the mesher's own triangles,
// and what an edit removed and added of each material (world/material_volume.hpp).
#include "server/mesh/surface_query.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "server/mesh/region_mesher.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::mesh {
namespace {

using world::ChunkCoord;

// Terrain of seed 1 in chunks -2..1 on every axis, with caves blown into it so that rays
// meet overhangs and undersides too.
world::ChunkMap terrain() {
  const world::TerrainGenerator gen(1);
  world::ChunkMap map;
  for (int z = -2; z <= 1; ++z)
    for (int y = -2; y <= 1; ++y)
      for (int x = -2; x <= 1; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  for (const world::Vec3 at :
       {world::Vec3{5, -6, 3}, world::Vec3{-12, -3, -9}, world::Vec3{20, -10, -20}}) {
    const world::Edit e = world::Explosion{at, 9, 3};
    for (const ChunkCoord& c : world::chunks_overlapping(world::touched_box(e)))
      if (world::Chunk* chunk = map.find(c)) world::apply_edit(e, c, *chunk, nullptr);
  }
  return map;
}

struct Triangle {
  std::array<std::array<double, 3>, 3> p;
  std::array<uint8_t, 3> material;
};

// Every triangle the mesher makes of chunks -1..0 on every axis, in world coordinates.
std::vector<Triangle> triangles(const world::ChunkMap& map) {
  const ChunkBox box{{-1, -1, -1}, {0, 0, 0}};
  const std::vector<ChunkMesh> meshes = mesh_chunks(map, box);
  std::vector<Triangle> out;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const ChunkCoord c = box.at(i);
    const ChunkMesh& m = meshes[i];
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      Triangle tri;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = m.indices[3 * t + k];
        tri.p[k] = {c.x * 32.0 + m.positions[v].x, c.y * 32.0 + m.positions[v].y,
                    c.z * 32.0 + m.positions[v].z};
        tri.material[k] = m.materials[v];
      }
      out.push_back(tri);
    }
  }
  return out;
}

// The nearest triangle along the ray within max (brute force), or infinity.
double nearest(const std::vector<Triangle>& tris, const Ray& r) {
  double best = std::numeric_limits<double>::infinity();
  const double o[3] = {r.origin.x, r.origin.y, r.origin.z};
  const double d[3] = {r.direction.x, r.direction.y, r.direction.z};
  for (const Triangle& tri : tris) {
    double e1[3], e2[3], s[3];
    for (int a = 0; a < 3; ++a)
      e1[a] = tri.p[1][a] - tri.p[0][a], e2[a] = tri.p[2][a] - tri.p[0][a],
      s[a] = o[a] - tri.p[0][a];
    const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                         d[0] * e2[1] - d[1] * e2[0]};
    const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (std::abs(det) < 1e-12) continue;
    const double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
    const double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                         s[0] * e1[1] - s[1] * e1[0]};
    const double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
    const double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    if (u < 0 || v < 0 || u + v > 1 || t < 0 || t > r.max_distance) continue;
    best = std::min(best, t);
  }
  return best;
}

// How far the ray stays inside [-32, 32) on every axis.
double inside_for(const Ray& r) {
  double t = std::numeric_limits<double>::infinity();
  const double o[3] = {r.origin.x, r.origin.y, r.origin.z};
  const double d[3] = {r.direction.x, r.direction.y, r.direction.z};
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0) t = std::min(t, (32 - o[a]) / d[a]);
    if (d[a] < 0) t = std::min(t, (-32 - o[a]) / d[a]);
  }
  return t;
}

TEST(SurfaceQuery, ARayHitsTheNearestTriangleTheMesherMakes) {
  const world::ChunkMap map = terrain();
  const std::vector<Triangle> tris = triangles(map);
  ASSERT_GT(tris.size(), 1000u);
  ChunkMapSource source(map);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-30, 30), dir(-1, 1);
  int hits = 0, misses = 0;
  for (int i = 0; i < 400; ++i) {
    Ray r;
    r.origin = {pos(rng), pos(rng), pos(rng)};
    float d[3] = {dir(rng), dir(rng), dir(rng)};
    if (i % 4 == 0) d[0] = d[2] = 0, d[1] = -1;  // straight down, along cell faces too
    if (i % 8 == 1) r.origin.x = std::round(r.origin.x), r.origin.z = std::round(r.origin.z);
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (len < 0.1f) continue;
    r.direction = {d[0] / len, d[1] / len, d[2] / len};
    r.max_distance = static_cast<float>(std::min(60.0, inside_for(r) - 0.01));
    if (r.max_distance <= 0) continue;
    const RayHit hit = raycast(source, r);
    const double expected = nearest(tris, r);
    ASSERT_TRUE(hit.complete);
    ASSERT_EQ(hit.hit, std::isfinite(expected)) << "ray " << i;
    if (!hit.hit) {
      ++misses;
      continue;
    }
    ++hits;
    EXPECT_NEAR(hit.distance, expected, 1e-3) << "ray " << i;
    EXPECT_NEAR(hit.point.x, r.origin.x + expected * r.direction.x, 2e-3);
    EXPECT_NEAR(hit.point.y, r.origin.y + expected * r.direction.y, 2e-3);
    const double n = std::sqrt(hit.normal.x * hit.normal.x + hit.normal.y * hit.normal.y +
                               hit.normal.z * hit.normal.z);
    EXPECT_NEAR(n, 1.0, 1e-4);
    // The normal faces the side the ray came from when it enters the ground from the air.
    EXPECT_NE(hit.material, world::kAir);
  }
  EXPECT_GT(hits, 100);
  EXPECT_GT(misses, 10);
}

TEST(SurfaceQuery, GroundFromTheSkyIsTheTopSurfaceFacingUp) {
  const world::ChunkMap map = terrain();
  const std::vector<Triangle> tris = triangles(map);
  ChunkMapSource source(map);
  for (float x = -28.5f; x < 30; x += 7.25f)
    for (float z = -29.0f; z < 30; z += 6.0f) {  // whole z: along cell faces
      const Ray down{{x, 31.5f, z}, {0, -1, 0}, 63};
      const RayHit hit = raycast(source, down);
      const double expected = nearest(tris, down);
      ASSERT_EQ(hit.hit, std::isfinite(expected));
      if (!hit.hit) continue;
      EXPECT_NEAR(hit.distance, expected, 1e-3);
      EXPECT_GT(hit.normal.y, 0.0f) << x << "," << z;  // from the air: a floor
    }
}

// A source that has only some chunks: a ray reaching another stops there, incomplete.
class PartialSource final : public ChunkSource {
 public:
  explicit PartialSource(const world::ChunkMap& map) : map_(map) {}
  const world::Chunk* chunk(ChunkCoord c) override { return c.x < 0 ? map_.find(c) : nullptr; }

 private:
  const world::ChunkMap& map_;
};

TEST(SurfaceQuery, ARayIntoChunksTheSourceCannotGiveStopsIncompleteWhereTheyBegin) {
  const world::ChunkMap map = terrain();
  PartialSource source(map);
  // Along x, well above the ground: nothing to hit before x = 0, where chunks run out.
  const RayHit hit = raycast(source, Ray{{-40, 20, 5}, {1, 0, 0}, 80});
  EXPECT_FALSE(hit.hit);
  EXPECT_FALSE(hit.complete);
  EXPECT_GT(hit.distance, 36.0f);  // the gradients of cell -2 read x = 0 already
  EXPECT_LE(hit.distance, 40.0f);
  std::string d, m;
  EXPECT_FALSE(read_samples(source, {{-2, 0, 0}, {1, 1, 1}}, d, m));
}

TEST(SurfaceQuery, SamplesOfABoxAcrossChunksAreTheMapsXFastest) {
  const world::ChunkMap map = terrain();
  ChunkMapSource source(map);
  const world::VoxelBox box{{-3, -5, -2}, {4, 3, 1}};
  std::string d, m;
  ASSERT_TRUE(read_samples(source, box, d, m));
  ASSERT_EQ(m.size(), 8u * 9 * 4);
  ASSERT_EQ(d.size(), 2 * m.size());
  size_t i = 0;
  for (int z = box.lo[2]; z <= box.hi[2]; ++z)
    for (int y = box.lo[1]; y <= box.hi[1]; ++y)
      for (int x = box.lo[0]; x <= box.hi[0]; ++x, ++i) {
        const world::Sample s = map.sample_at(x, y, z);
        const auto density = static_cast<int16_t>(static_cast<uint8_t>(d[2 * i]) |
                                                  static_cast<uint8_t>(d[2 * i + 1]) << 8);
        ASSERT_EQ(density, s.density);
        ASSERT_EQ(static_cast<uint8_t>(m[i]), s.material);
      }
}

}  // namespace
}  // namespace vox::mesh

namespace vox::world {
namespace {

std::vector<MaterialVolume> volumes(const VolumeTally& t) {
  std::vector<MaterialVolume> out;
  t.materials([&](const MaterialVolume& v) { out.push_back(v); });
  return out;
}

TEST(MaterialYield, AWholeVoxelOfRockCarvedIsOneVoxelRemoved) {
  VolumeTally t;
  t.add({kDensityMax, 1}, {kDensityMin, 1});
  t.add({0, 3}, {kDensityMax, 3});            // a surface sample filled: half a voxel added
  t.add({kDensityMax, 1}, {kDensityMax, 7});  // painted: stone gone, grass there
  const auto v = volumes(t);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_EQ(v[0].material, 1);
  EXPECT_DOUBLE_EQ(v[0].removed, 2.0);
  EXPECT_DOUBLE_EQ(v[0].added, 0.0);
  EXPECT_EQ(v[1].material, 3);
  EXPECT_NEAR(v[1].added, 0.5, 1e-4);
  EXPECT_EQ(v[2].material, 7);
  EXPECT_DOUBLE_EQ(v[2].added, 1.0);
}

// An explosion's yield, however many chunks it spans, is what each material's share of
// the samples (occupancy: density mapped onto 0..1) lost or gained.
TEST(MaterialYield, AnEditsYieldIsEachMaterialsChangeOfOccupancy) {
  const TerrainGenerator gen(1);
  ChunkMap before, after;
  for (int z = -1; z <= 0; ++z)
    for (int y = -1; y <= 0; ++y)
      for (int x = -1; x <= 0; ++x) {
        before.insert({x, y, z}, gen.generate({x, y, z}));
        after.insert({x, y, z}, gen.generate({x, y, z}));
      }
  for (const Edit& e :
       {Edit{Explosion{{0.5f, -2, 0.5f}, 10, 3}}, Edit{Brush{{3, 4, -2}, 6, 2, false, Material{5}}},
        Edit{Paint{{-4, -1, 2}, 5, 9}}}) {
    VolumeTally tally;
    for (const ChunkCoord& c : chunks_overlapping(touched_box(e))) {
      VolumeTally part;
      apply_edit(e, c, *after.find(c), nullptr, {}, &part);
      tally.merge(part);
    }
    std::array<double, 256> change{};
    for (int z = -32; z < 32; ++z)
      for (int y = -32; y < 32; ++y)
        for (int x = -32; x < 32; ++x) {
          const Sample a = before.sample_at(x, y, z), b = after.sample_at(x, y, z);
          change[a.material] -= double(a.density - kDensityMin) / kVoxelSteps;
          change[b.material] += double(b.density - kDensityMin) / kVoxelSteps;
        }
    std::array<double, 256> got{};
    for (const MaterialVolume& m : volumes(tally)) got[m.material] = m.added - m.removed;
    double moved = 0;
    for (int m = 1; m < 256; ++m) {
      EXPECT_NEAR(got[m], change[m], 1e-6) << "material " << m;
      moved += std::abs(change[m]);
    }
    EXPECT_GT(moved, 50);
    before = ChunkMap();
    for (const auto& [c, chunk] : after) before.insert(c, chunk);
  }
}

}  // namespace
}  // namespace vox::world
