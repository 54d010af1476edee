#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "server/mesh/region_mesher.hpp"
#include "tests/mesh_test_util.hpp"

namespace vox::mesh {
namespace {

using world::ChunkMap;

TEST(ClosedSurface, SphereIsClosedManifoldWithAnalyticAreaAndVolume) {
  const float cx = 32.3f, cy = 31.6f, cz = 32.8f, r = 10.0f;
  const ChunkBox box{{0, 0, 0}, {1, 1, 1}};  // the sphere crosses all 8 chunks
  ChunkMap map;
  test::fill_from_field(map, box, [&](float x, float y, float z) {
    return (r - std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz))) * 0.25f;
  });
  const ChunkMesh m = mesh_region(map, box, 2);
  const test::Topology t = test::analyse(m);
  test::expect_closed_manifold(t);
  EXPECT_EQ(t.components, 1u);
  const double pi = std::numbers::pi;
  EXPECT_NEAR(t.area, 4 * pi * r * r, 0.02 * 4 * pi * r * r);
  EXPECT_NEAR(t.volume, 4.0 / 3.0 * pi * r * r * r, 0.02 * 4.0 / 3.0 * pi * r * r * r);
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const Vec3f p = m.positions[v], n = m.normals[v];
    EXPECT_GT(n.x * (p.x - cx) + n.y * (p.y - cy) + n.z * (p.z - cz), 0.0f)
        << "normal must point to air";
  }
}

// Metaballs (seed 004): field sum(s_i / |m_i - p|^g), solid where the field exceeds 1.
TEST(ClosedSurface, MetaballsGiveClosedManifoldWithEulerTwoPerComponent) {
  struct Ball {
    float x, y, z, s;
  };
  const Ball balls[] = {{27.3f, 30.2f, 31.1f, 49.0f},
                        {36.6f, 33.1f, 30.4f, 36.0f},
                        {32.2f, 27.7f, 38.9f, 30.0f},
                        {52.4f, 50.6f, 49.3f, 16.0f}};  // the last one stands apart
  const float g = 2.0f;
  const ChunkBox box{{0, 0, 0}, {1, 1, 1}};
  ChunkMap map;
  test::fill_from_field(map, box, [&](float x, float y, float z) {
    float f = 0;
    for (const Ball& b : balls) {
      const float d2 = (x - b.x) * (x - b.x) + (y - b.y) * (y - b.y) + (z - b.z) * (z - b.z);
      f += b.s / std::pow(d2, g / 2);
    }
    return f - 1.0f;
  });
  const test::Topology t = test::analyse(mesh_region(map, box, 2));
  test::expect_closed_manifold(t);
  EXPECT_EQ(t.components, 2u);
}

}  // namespace
}  // namespace vox::mesh
