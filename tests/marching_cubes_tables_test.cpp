#include "server/mesh/marching_cubes_tables.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "server/mesh/marching_cubes.hpp"

namespace vox::mesh {
namespace {

int triangles_in(int cube) {
  int n = 0;
  while (n < 5 && triTable[cube][3 * n] >= 0) ++n;
  return n;
}

TEST(MarchingCubesTables, EdgeTableMarksExactlyTheEdgesWithDifferentCorners) {
  EXPECT_EQ(edgeTable[0], 0);
  EXPECT_EQ(edgeTable[255], 0);
  EXPECT_EQ(edgeTable[1], 0x109);  // Bourke's first entries
  EXPECT_EQ(edgeTable[3], 0x30a);
  for (int c = 0; c < 256; ++c) {
    for (int e = 0; e < 12; ++e) {
      const bool a = (c >> kEdgeCorners[e][0]) & 1, b = (c >> kEdgeCorners[e][1]) & 1;
      EXPECT_EQ(((edgeTable[c] >> e) & 1) != 0, a != b) << "case " << c << " edge " << e;
    }
  }
}

TEST(MarchingCubesTables, TrianglesUseEveryCutEdgeAndNothingElse) {
  for (int c = 0; c < 256; ++c) {
    unsigned used = 0;
    const int n = triangles_in(c);
    EXPECT_EQ(triTable[c][3 * n], -1) << "case " << c << " is not terminated";
    for (int k = 0; k < 3 * n; ++k) used |= 1u << triTable[c][k];
    EXPECT_EQ(used, edgeTable[c]) << "case " << c;
    // A surface patch of k polygons over m cut edges has m - 2k triangles, >= m/3.
    EXPECT_GE(3 * n, std::popcount(static_cast<unsigned>(edgeTable[c])));
  }
}

// A fan triangle flat in a face of the cube (cases with two air corners diagonal on a face
// and every other corner solid) met the same triangle of the cell across that face, wound
// the other way: a fin of zero thickness, its edges in four triangles. Found on coarse
// level-of-detail terrain.
TEST(MarchingCubesTables, NoTriangleLiesFlatInAFaceOfTheCube) {
  for (int c = 0; c < 256; ++c) {
    for (int t = 0; t < 3 * triangles_in(c); t += 3) {
      for (const auto& face : kCubeFaces) {
        int on = 0;
        for (int i = 0; i < 3; ++i) {
          const int e = triTable[c][t + i];
          for (int k = 0; k < 4; ++k) {
            const int a = face[k], b = face[(k + 1) % 4];
            on += (kEdgeCorners[e][0] == a && kEdgeCorners[e][1] == b) ||
                  (kEdgeCorners[e][0] == b && kEdgeCorners[e][1] == a);
          }
        }
        EXPECT_LT(on, 3) << "case " << c << " triangle " << t / 3;
      }
    }
  }
}

TEST(MarchingCubesTables, ComplementaryCasesCutTheSameEdges) {
  for (int c = 0; c < 256; ++c) EXPECT_EQ(edgeTable[c], edgeTable[255 - c]);
}

// Meshes one cell whose corners follow `cube` (|density| random), through the real mesher.
ChunkMesh mesh_one_cell(unsigned cube, std::mt19937& rng, std::array<int, 8>& corner_density) {
  PaddedBlock block;
  block.cells = {1, 1, 1};
  std::uniform_int_distribution<int> magnitude(1, 32767);
  for (int c = 0; c < 8; ++c)
    corner_density[c] = ((cube >> c) & 1) ? magnitude(rng) : -magnitude(rng);
  // Fill the whole block from the nearest corner so central differences see the same field.
  for (int z = -1; z <= 33; ++z)
    for (int y = -1; y <= 33; ++y)
      for (int x = -1; x <= 33; ++x) {
        const int cx = x <= 0 ? 0 : 1, cy = y <= 0 ? 0 : 1, cz = z <= 0 ? 0 : 1;
        int corner = 0;
        for (int k = 0; k < 8; ++k)
          if (kCubeCorner[k][0] == cx && kCubeCorner[k][1] == cy && kCubeCorner[k][2] == cz)
            corner = k;
        block.density[PaddedBlock::index(x, y, z)] =
            static_cast<world::Density>(corner_density[corner]);
        block.material[PaddedBlock::index(x, y, z)] = static_cast<world::Material>(corner + 1);
      }
  MeshScratch scratch;
  ChunkMesh mesh;
  mesh_chunk(block, scratch, mesh);
  return mesh;
}

TEST(MarchingCubes, EveryConfigurationPutsVerticesOnItsCutEdges) {
  std::mt19937 rng(11);
  for (unsigned cube = 0; cube < 256; ++cube) {
    std::array<int, 8> d{};
    const ChunkMesh m = mesh_one_cell(cube, rng, d);
    if (cube == 0 || cube == 255) {
      EXPECT_TRUE(m.empty()) << "case " << cube;
      EXPECT_EQ(m.vertex_count(), 0u);
      continue;
    }
    EXPECT_EQ(m.vertex_count(),
              static_cast<size_t>(std::popcount(static_cast<unsigned>(edgeTable[cube]))));
    EXPECT_EQ(m.triangle_count(), static_cast<size_t>(triangles_in(static_cast<int>(cube))));
    for (size_t v = 0; v < m.vertex_count(); ++v) {
      const Vec3f p = m.positions[v];
      // Find the edge the vertex is on: two coordinates at a corner value, one inside.
      bool on_cut_edge = false;
      for (int e = 0; e < 12; ++e) {
        const auto& a = kCubeCorner[kEdgeCorners[e][0]];
        const auto& b = kCubeCorner[kEdgeCorners[e][1]];
        bool on_line = true;
        const float pc[3] = {p.x, p.y, p.z};
        for (int k = 0; k < 3; ++k) {
          if (a[k] == b[k])
            on_line &= pc[k] == static_cast<float>(a[k]);
          else
            on_line &= pc[k] >= 0.0f && pc[k] <= 1.0f;
        }
        if (on_line && ((edgeTable[cube] >> e) & 1)) {
          on_cut_edge = true;
          const int solid_end = d[kEdgeCorners[e][0]] > 0 ? kEdgeCorners[e][0] : kEdgeCorners[e][1];
          EXPECT_EQ(m.materials[v], solid_end + 1)
              << "case " << cube << ": material of the solid end";
        }
      }
      EXPECT_TRUE(on_cut_edge) << "case " << cube << " vertex " << v;
    }
  }
}

TEST(MarchingCubes, EveryConfigurationWindsTrianglesTowardAir) {
  // With midpoint vertices, each triangle's normal must point from the solid ends of
  // its edges toward the air ends (summed over its three edges: a fan triangle of a
  // non-planar polygon may stand across one of them, or sideways in a tunnel case, so it
  // may score 0 but never less; the case as a whole must score above 0).
  for (unsigned cube = 1; cube < 255; ++cube) {
    const int n = triangles_in(static_cast<int>(cube));
    float case_total = 0;
    for (int t = 0; t < n; ++t) {
      float p[3][3], dir[3][3];
      for (int k = 0; k < 3; ++k) {
        const int e = triTable[cube][3 * t + k];
        const int a = kEdgeCorners[e][0], b = kEdgeCorners[e][1];
        const int solid = ((cube >> a) & 1) ? a : b, air = solid == a ? b : a;
        for (int j = 0; j < 3; ++j) {
          p[k][j] = 0.5f * (kCubeCorner[a][j] + kCubeCorner[b][j]);
          dir[k][j] = static_cast<float>(kCubeCorner[air][j] - kCubeCorner[solid][j]);
        }
      }
      const float u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
      const float w[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
      const float nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                            u[0] * w[1] - u[1] * w[0]};
      float toward_air = 0;
      for (int k = 0; k < 3; ++k)
        toward_air += nrm[0] * dir[k][0] + nrm[1] * dir[k][1] + nrm[2] * dir[k][2];
      EXPECT_GE(toward_air, 0.0f) << "case " << cube << " triangle " << t;
      case_total += toward_air;
    }
    EXPECT_GT(case_total, 0.0f) << "case " << cube;
  }
}

}  // namespace
}  // namespace vox::mesh

namespace vox::mesh {
namespace {

// docs/marching_cubes_tables.txt is what a client in another language decodes with; it
// must say exactly what the code does.
TEST(MarchingCubesTables, PublishedTableFileMatchesTheCode) {
  std::ifstream in(std::string(VOXEL_SOURCE_DIR) + "/docs/marching_cubes_tables.txt");
  ASSERT_TRUE(in) << "docs/marching_cubes_tables.txt is missing";
  std::string line;
  int expected_case = 0;
  uint32_t revision = 0;
  while (std::getline(in, line)) {
    if (line.rfind("# revision ", 0) == 0)
      revision = static_cast<uint32_t>(std::stoul(line.substr(11)));
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    int c = -1;
    std::string mask;
    fields >> c >> mask;
    ASSERT_EQ(c, expected_case);
    EXPECT_EQ(std::stoi(mask, nullptr, 16), edgeTable[c]) << "case " << c;
    std::vector<int> edges;
    for (int e; fields >> e;) edges.push_back(e);
    std::vector<int> code;
    for (int k = 0; k < 16 && triTable[c][k] >= 0; ++k) code.push_back(triTable[c][k]);
    EXPECT_EQ(edges, code) << "case " << c;
    ++expected_case;
  }
  EXPECT_EQ(expected_case, 256);
  EXPECT_EQ(revision, kMeshTableRevision) << "the file's revision line";
}

}  // namespace
}  // namespace vox::mesh
