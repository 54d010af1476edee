// weld_chunk_grid on grids with holes and borders, as `voxel-cli export` builds them: the
// chunks of a view (a sphere) that have triangles, in a dense grid over their bounding box.
#include "server/mesh/mesh_welder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "proto/mesh_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::mesh {
namespace {

using world::kChunkSize;

struct ChunkGrid {
  std::array<int, 3> dims{};
  Vec3f origin;
  std::vector<ChunkMesh> parts;  // empty where a chunk is missing

  std::array<int, 3> pos(size_t i) const {
    return {static_cast<int>(i % dims[0]), static_cast<int>(i / dims[0] % dims[1]),
            static_cast<int>(i / dims[0] / dims[1])};
  }
  Vec3f world(size_t i, const Vec3f& l) const {
    const auto g = pos(i);
    return {origin.x + 32.0f * g[0] + l.x, origin.y + 32.0f * g[1] + l.y,
            origin.z + 32.0f * g[2] + l.z};
  }
};

// What a client holds for a view of `radius` chunks around chunk (0, 0, 0): every chunk
// of the sphere (or of the whole box) that has triangles, encoded and decoded; the rest of
// the box is missing.
ChunkGrid view_of_terrain(uint64_t seed, int radius, bool sphere = true) {
  const world::TerrainGenerator gen(seed);
  world::ChunkMap map;
  const int r = radius + 1;
  for (int z = -r; z <= r; ++z)
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  PaddedBlock block;
  MeshScratch topology;
  proto::CodecScratch codec;
  ChunkMesh mesh;
  proto::Bytes encoding;
  const int side = 2 * radius + 1;
  ChunkGrid grid{{side, side, side}, {-32.0f * radius, -32.0f * radius, -32.0f * radius}, {}};
  grid.parts.resize(static_cast<size_t>(side) * side * side);
  for (size_t i = 0; i < grid.parts.size(); ++i) {
    const auto g = grid.pos(i);
    const world::ChunkCoord c{g[0] - radius, g[1] - radius, g[2] - radius};
    if (sphere && c.x * c.x + c.y * c.y + c.z * c.z > radius * radius) continue;
    gather_padded_block(map, c, block);
    mesh_chunk(block, topology, mesh);
    if (mesh.empty()) continue;  // the server never sends an empty chunk
    proto::encode_mesh(mesh, topology, block.cells, codec, encoding);
    auto decoded = proto::decode_mesh(encoding);
    EXPECT_TRUE(decoded) << decoded.error();
    if (decoded) grid.parts[i] = std::move(*decoded);
  }
  return grid;
}

// Exactly, in 1/1024 steps (world coordinates here are multiples of 1/1024 under 2^13).
bool has_zero_area(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  auto fixed = [](const Vec3f& p) {
    return std::array<int64_t, 3>{std::llround(p.x * 1024.0), std::llround(p.y * 1024.0),
                                  std::llround(p.z * 1024.0)};
  };
  const auto pa = fixed(a), pb = fixed(b), pc = fixed(c);
  const int64_t u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  const int64_t w[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
  return u[1] * w[2] == u[2] * w[1] && u[2] * w[0] == u[0] * w[2] && u[0] * w[1] == u[1] * w[0];
}

bool on_face(const Vec3f& l) {
  return l.x == 0 || l.y == 0 || l.z == 0 || l.x == kChunkSize || l.y == kChunkSize ||
         l.z == kChunkSize;
}

bool at_sample(const Vec3f& l) {
  return l.x == std::trunc(l.x) && l.y == std::trunc(l.y) && l.z == std::trunc(l.z);
}

// What welding should give: one vertex per used vertex inside a chunk away from a sample,
// one per world position of the used vertices on chunk faces or at samples.
size_t expected_vertex_count(const ChunkGrid& grid) {
  size_t inside = 0;
  std::set<std::array<float, 3>> on_faces;
  for (size_t i = 0; i < grid.parts.size(); ++i) {
    const ChunkMesh& p = grid.parts[i];
    std::vector<bool> used(p.vertex_count(), false);
    for (uint32_t index : p.indices) used[index] = true;
    for (size_t v = 0; v < p.vertex_count(); ++v) {
      if (!used[v]) continue;
      if (!on_face(p.positions[v]) && !at_sample(p.positions[v])) {
        ++inside;
        continue;
      }
      const Vec3f w = grid.world(i, p.positions[v]);
      on_faces.insert({w.x, w.y, w.z});
    }
  }
  return inside + on_faces.size();
}

struct WeldFaults {
  size_t out_of_range = 0, repeated = 0, zero_area = 0, outside_own_chunk = 0, moved = 0,
         unused_vertices = 0;
};

// The welded triangles come part by part, in order; each must be its part's triangle at
// the same world positions.
WeldFaults check_weld(const ChunkGrid& grid, const ChunkMesh& welded) {
  WeldFaults f;
  size_t t = 0;
  std::vector<bool> used(welded.vertex_count(), false);
  for (size_t i = 0; i < grid.parts.size(); ++i) {
    const ChunkMesh& p = grid.parts[i];
    const Vec3f lo = grid.world(i, {0, 0, 0}), hi = grid.world(i, {32, 32, 32});
    for (size_t k = 0; k < p.indices.size(); k += 3, t += 3) {
      const uint32_t w[3] = {welded.indices[t], welded.indices[t + 1], welded.indices[t + 2]};
      if (w[0] >= welded.vertex_count() || w[1] >= welded.vertex_count() ||
          w[2] >= welded.vertex_count()) {
        ++f.out_of_range;
        continue;
      }
      f.repeated += (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) ? 1 : 0;
      const Vec3f a = welded.positions[w[0]], b = welded.positions[w[1]],
                  c = welded.positions[w[2]];
      f.zero_area += has_zero_area(a, b, c) ? 1 : 0;
      bool outside = false, moved = false;
      for (int j = 0; j < 3; ++j) {
        const Vec3f q = welded.positions[w[j]];
        used[w[j]] = true;
        outside |= q.x < lo.x || q.y < lo.y || q.z < lo.z || q.x > hi.x || q.y > hi.y || q.z > hi.z;
        moved |= !(q == grid.world(i, p.positions[p.indices[k + j]]));
      }
      f.outside_own_chunk += outside ? 1 : 0;
      f.moved += moved ? 1 : 0;
    }
  }
  EXPECT_EQ(t, welded.indices.size()) << "the welded mesh should have exactly the parts' triangles";
  for (bool u : used) f.unused_vertices += u ? 0 : 1;
  return f;
}

void expect_welds(const ChunkGrid& grid) {
  const ChunkMesh welded = weld_chunk_grid(grid.parts, grid.dims, grid.origin, 2);
  const WeldFaults f = check_weld(grid, welded);
  EXPECT_EQ(f.out_of_range, 0u);
  EXPECT_EQ(f.repeated, 0u);
  EXPECT_EQ(f.zero_area, 0u);
  EXPECT_EQ(f.outside_own_chunk, 0u);
  EXPECT_EQ(f.moved, 0u) << "of " << welded.triangle_count() << " triangles";
  EXPECT_EQ(f.unused_vertices, 0u);
  EXPECT_EQ(welded.vertex_count(), expected_vertex_count(grid));
}

// Issue 12 item 7: vertices on the face of a chunk missing from the grid were looked up in
// that chunk, not found, and became index 0: 1,448 of 107,118 exported faces were spikes.
TEST(MeshWelder, VertexOnTheFaceOfAMissingChunkStaysWithItsChunk) {
  for (uint64_t seed : {5ull, 1ull, 2ull}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const ChunkGrid grid = view_of_terrain(seed, 3);
    size_t present = 0, triangles = 0;
    for (const ChunkMesh& p : grid.parts) {
      present += p.empty() ? 0 : 1;
      triangles += p.triangle_count();
    }
    ASSERT_GT(present, 20u);
    ASSERT_LT(present, grid.parts.size() / 2) << "the grid should have holes";
    ASSERT_GT(triangles, 50000u);
    expect_welds(grid);
  }
}

// Holes next to chunk edges and corners too, where up to eight chunks hold a vertex.
TEST(MeshWelder, WeldsAGridWithRandomHoles) {
  std::mt19937 rng(12);
  for (uint64_t seed : {3ull, 7ull}) {
    const ChunkGrid whole = view_of_terrain(seed, 2, false);
    for (unsigned one_in : {2u, 3u, 5u}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", one chunk in " + std::to_string(one_in) +
                   " missing");
      ChunkGrid grid = whole;
      for (ChunkMesh& p : grid.parts) {
        if (rng() % one_in == 0) p = ChunkMesh{};
      }
      expect_welds(grid);
    }
  }
}

TEST(MeshWelder, WeldsAWholeBoxAndAnEmptyOne) {
  ChunkGrid grid = view_of_terrain(4, 2, false);
  expect_welds(grid);
  for (ChunkMesh& p : grid.parts) p = ChunkMesh{};
  expect_welds(grid);
}

}  // namespace
}  // namespace vox::mesh
