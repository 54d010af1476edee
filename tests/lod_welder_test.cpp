// weld_lod_parts: the chunks of a level-of-detail view joined into one mesh, as
// `voxel-cli export --lod-distance` writes it.
#include "server/mesh/lod_welder.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace vox::mesh {
namespace {

// One triangle with the given chunk-local corners, plus a vertex no triangle uses.
ChunkMesh triangle(const std::array<Vec3f, 3>& corners, uint8_t material) {
  ChunkMesh m;
  m.positions = {{9, 9, 9}, corners[0], corners[1], corners[2]};
  m.normals.assign(4, Vec3f{0, 1, 0});
  m.materials.assign(4, material);
  m.indices = {1, 2, 3};
  return m;
}

bool same(const ChunkMesh& a, const ChunkMesh& b) {
  const auto eq = [](const Vec3f& p, const Vec3f& q) {
    return p.x == q.x && p.y == q.y && p.z == q.z;
  };
  return a.indices == b.indices && a.materials == b.materials &&
         std::equal(a.positions.begin(), a.positions.end(), b.positions.begin(), b.positions.end(),
                    eq);
}

TEST(LodWelder, AVertexOnASeamBetweenLevelsIsOneVertexAndUnusedOnesDrop) {
  // World (32, 5, 5): local (0, 5, 5) of level-0 chunk (1, 0, 0) and local (16, 2.5, 2.5)
  // of level-1 chunk (0, 0, 0).
  const ChunkMesh fine = triangle({Vec3f{0, 5, 5}, Vec3f{1, 5, 5}, Vec3f{0, 6, 5}}, 1);
  const ChunkMesh coarse =
      triangle({Vec3f{16, 2.5f, 2.5f}, Vec3f{15, 2.5f, 2.5f}, Vec3f{16, 2, 3}}, 2);
  const ChunkMesh m = weld_lod_parts({{0, {1, 0, 0}, &fine}, {1, {0, 0, 0}, &coarse}});
  EXPECT_EQ(m.vertex_count(), 5u);
  EXPECT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(m.indices[0], m.indices[3]) << "the seam vertex is shared";
  EXPECT_EQ(m.positions[m.indices[4]].x, 30.0f) << "level 1: two voxels per cell";
}

TEST(LodWelder, TheSamePartsInAnyOrderWeldToTheSameMesh) {
  // What broke: `voxel-cli export --lod-distance` numbered vertices in the order chunks
  // arrived, so two exports of one view were different files.
  std::vector<ChunkMesh> meshes;
  std::vector<LodPart> parts;
  for (uint32_t level = 0; level < 3; ++level)
    for (int x = -2; x < 2; ++x)
      for (int z = -2; z < 2; ++z) {
        // Corners on the chunk's faces, shared with the neighbours of the same level.
        meshes.push_back(triangle({Vec3f{0, 1, 0}, Vec3f{32, 1, 0}, Vec3f{0, 1, 32}},
                                  static_cast<uint8_t>(level + 1)));
        parts.push_back({level, {x, 0, z}, nullptr});
      }
  for (size_t i = 0; i < parts.size(); ++i) parts[i].mesh = &meshes[i];
  const ChunkMesh first = weld_lod_parts(parts);
  EXPECT_LT(first.vertex_count(), 3 * parts.size()) << "shared corners welded";
  std::mt19937 rng(7);
  for (int round = 0; round < 5; ++round) {
    std::shuffle(parts.begin(), parts.end(), rng);
    EXPECT_TRUE(same(weld_lod_parts(parts), first)) << "order " << round;
  }
}

}  // namespace
}  // namespace vox::mesh
