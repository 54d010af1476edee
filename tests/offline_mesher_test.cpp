// The offline volume mesher (server/mesh/volume_mesher.hpp) on small volumes: VTK's
// partition with samples exactly on the level (against a per-cell reference), streaming
// from floats equal to meshing a quantised copy, signs kept by quantisation, tiny values,
// percentiles and voxel spacing.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "server/mesh/marching_cubes_tables.hpp"
#include "server/mesh/volume_mesher.hpp"

namespace vox::mesh {
namespace {

// Small integers around iso 1 on a 40^3 grid crossing chunk faces: many samples exactly on
// the level, every edge fraction a multiple of 1/4 at worst (exact at 1/1024 steps).
Volume integer_volume() {
  Volume v;
  v.dims = {40, 37, 35};
  for (int z = 0; z < v.dims[2]; ++z)
    for (int y = 0; y < v.dims[1]; ++y)
      for (int x = 0; x < v.dims[0]; ++x) {
        const uint32_t h = static_cast<uint32_t>(x + 40 * (y + 37 * z)) * 2654435761u;
        const int ball =
            13 - static_cast<int>(std::sqrt(
                     float((x - 20) * (x - 20) + (y - 18) * (y - 18) + (z - 17) * (z - 17))));
        v.values.push_back(static_cast<float>(z < 12 ? static_cast<int>((h >> 16) % 4) - 1
                                                     : std::clamp(ball, -2, 3)));
      }
  return v;
}

// Per-cell marching cubes from the tables with solid = value >= iso (VTK's partition) and
// exact positions in double: the triangles of non-zero area.
size_t reference_nonzero_triangles(const Volume& v, float iso) {
  auto at = [&](int x, int y, int z) {
    return static_cast<double>(v.values[x + v.dims[0] * (y + static_cast<size_t>(v.dims[1]) * z)]);
  };
  size_t count = 0;
  for (int z = 0; z + 1 < v.dims[2]; ++z)
    for (int y = 0; y + 1 < v.dims[1]; ++y)
      for (int x = 0; x + 1 < v.dims[0]; ++x) {
        double val[8];
        unsigned cube = 0;
        for (int c = 0; c < 8; ++c) {
          val[c] = at(x + kCubeCorner[c][0], y + kCubeCorner[c][1], z + kCubeCorner[c][2]);
          cube |= (val[c] >= iso ? 1u : 0u) << c;
        }
        std::array<std::array<double, 3>, 12> p{};
        for (int e = 0; e < 12; ++e) {
          const int a = kEdgeCorners[e][0], b = kEdgeCorners[e][1];
          if ((val[a] >= iso) == (val[b] >= iso)) continue;
          const double t = (iso - val[a]) / (val[b] - val[a]);
          for (int k = 0; k < 3; ++k)
            p[e][k] = kCubeCorner[a][k] + t * (kCubeCorner[b][k] - kCubeCorner[a][k]);
        }
        for (const int8_t* tri = triTable[cube].data(); *tri >= 0; tri += 3) {
          const auto &a = p[tri[0]], &b = p[tri[1]], &c = p[tri[2]];
          const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
                       w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
          const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                               u[0] * w[1] - u[1] * w[0]};
          count += (n[0] != 0 || n[1] != 0 || n[2] != 0) ? 1 : 0;
        }
      }
  return count;
}

TEST(OfflineMesher, SamplesOnTheIsoLevelGiveTheReferenceTriangleCount) {
  const Volume v = integer_volume();
  const VolumeMeshOptions options{.iso = 1.0f, .invert = false, .threads = 2};
  const ChunkMesh m = mesh_float_volume({v.dims, v.values, {}}, options);
  const size_t reference = reference_nonzero_triangles(v, 1.0f);
  ASSERT_GT(reference, 10000u);
  EXPECT_EQ(m.triangle_count(), reference);
}

TEST(OfflineMesher, StreamingFromFloatsGivesTheQuantisedVolumesMeshAndReleasesEverySample) {
  const Volume v = integer_volume();
  for (bool invert : {false, true}) {
    const VolumeMeshOptions options{.iso = 0.5f, .invert = invert, .threads = 2};
    std::mutex m;
    std::vector<std::pair<size_t, size_t>> released;
    const FloatVolumeView view{v.dims, v.values, [&](size_t b, size_t e) {
                                 std::lock_guard lock(m);
                                 released.push_back({b, e});
                               }};
    const ChunkMesh streamed = mesh_float_volume(view, options);
    const ChunkMesh copied = mesh_volume(quantize_volume(v, options), 2);
    EXPECT_EQ(streamed.positions, copied.positions);
    EXPECT_EQ(streamed.indices, copied.indices);
    EXPECT_EQ(streamed.normals, copied.normals);
    // The scale pass released every sample; the layers then everything below the last one.
    std::sort(released.begin(), released.end());
    size_t covered = 0;
    for (const auto& [b, e] : released) {
      EXPECT_LE(b, covered);
      covered = std::max(covered, e);
    }
    EXPECT_EQ(covered, v.values.size());
  }
}

// A review found: below a largest distance of about 1e-34, 32767 / scale was infinite
// and every vertex landed at an edge's midpoint.
TEST(OfflineMesher, AVolumeOfTinyValuesGivesTheSameMeshAsItsScaledUpCopy) {
  Volume v = integer_volume();
  const ChunkMesh normal = mesh_float_volume({v.dims, v.values, {}}, {.iso = 0.5f, .threads = 2});
  for (float& x : v.values) x = std::ldexp(x, -125);  // exact: a power of two, still normal
  const ChunkMesh tiny =
      mesh_float_volume({v.dims, v.values, {}}, {.iso = std::ldexp(0.5f, -125), .threads = 2});
  EXPECT_EQ(tiny.positions, normal.positions);
  EXPECT_EQ(tiny.indices, normal.indices);
}

TEST(OfflineMesher, QuantisingKeepsTheSignOfEveryValueExactly) {
  Volume v;
  v.dims = {2, 2, 2};
  v.values = {1e6f, -1e6f, 1.0f + 1e-6f, 1.0f - 1e-6f, 1.0f, 0.0f, 2.0f, 1e-30f};
  const QuantizedVolume q = quantize_volume(v, {.iso = 1.0f});
  EXPECT_EQ(q.density[0], 32767);
  EXPECT_EQ(q.density[1], -32767);
  EXPECT_EQ(q.density[2], 1);   // above the level by far less than a step: still above
  EXPECT_EQ(q.density[3], -1);  // below it: still below
  EXPECT_EQ(q.density[4], 0);   // on it: solid (zero_is_solid), as VTK takes it
  EXPECT_TRUE(q.zero_is_solid);
  EXPECT_FALSE(quantize_volume(v, {.iso = 1.0f, .invert = true}).zero_is_solid);
  v.values[5] = std::numeric_limits<float>::quiet_NaN();
  try {
    (void)quantize_volume(v, {.iso = 1.0f});
    ADD_FAILURE() << "a NaN was quantised";
  } catch (const std::domain_error& e) {
    EXPECT_STREQ(e.what(), "value 5 is not finite");
  }
}

TEST(VolumePercentile, IsTheValueAtTheRankOfThePercentile) {
  std::vector<float> v;
  for (int i = 0; i < 1001; ++i) v.push_back(static_cast<float>((i * 7919) % 1001) * 0.5f);
  EXPECT_FLOAT_EQ(value_percentile(v, 0), 0.0f);
  EXPECT_FLOAT_EQ(value_percentile(v, 100), 500.0f);
  EXPECT_FLOAT_EQ(value_percentile(v, 50), 250.0f);
  EXPECT_FLOAT_EQ(value_percentile(v, 10), 50.0f);
  // Values crowded into one bin beside one far outlier still give the exact rank.
  std::vector<float> crowded(999, 1.0f);
  for (int i = 0; i < 999; ++i) crowded[i] = 1.0f + static_cast<float>(i) * 1e-6f;
  crowded.push_back(1e9f);
  EXPECT_FLOAT_EQ(value_percentile(crowded, 50), 1.0f + 500 * 1e-6f);
  EXPECT_FLOAT_EQ(value_percentile(std::vector<float>(5, 3.0f), 37), 3.0f);
  // A review found: a NaN reached a float-to-index cast before any finiteness check.
  EXPECT_THROW(value_percentile(std::vector<float>{1.0f, std::nanf(""), 2.0f}, 50),
               std::domain_error);
}

TEST(VolumeSpacing, ScalesPositionsAndTurnsNormals) {
  ChunkMesh m;
  m.positions.push_back({1, 2, 3});
  const float r = 1.0f / std::sqrt(2.0f);
  m.normals.push_back({r, r, 0});
  m.materials.push_back(1);
  apply_spacing(m, {2.0f, 1.0f, 0.5f});
  EXPECT_EQ(m.positions[0], (Vec3f{2, 2, 1.5f}));
  // A 45-degree surface stretched twice as long in x leans towards x less: normal (1,2,0)/√5.
  EXPECT_NEAR(m.normals[0].x, 1.0f / std::sqrt(5.0f), 1e-6f);
  EXPECT_NEAR(m.normals[0].y, 2.0f / std::sqrt(5.0f), 1e-6f);
  EXPECT_NEAR(m.normals[0].z, 0.0f, 1e-6f);
}

}  // namespace
}  // namespace vox::mesh
