#include "server/mesh/marching_cubes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>

#include "server/mesh/region_mesher.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/alloc_counter.hpp"
#include "tests/mesh_test_util.hpp"

namespace vox::mesh {
namespace {

using world::ChunkCoord;
using world::ChunkMap;
using world::kChunkSize;

// A 3x3x3-chunk box around the terrain surface near a random column, loaded with a
// one-chunk margin.
ChunkBox load_terrain_region(ChunkMap& map, uint64_t seed, std::mt19937& rng) {
  const world::TerrainGenerator gen(seed);
  std::uniform_int_distribution<int> column(-8, 8);
  const int cx = column(rng), cz = column(rng);
  const float h = gen.height_at(cx * kChunkSize + 48, cz * kChunkSize + 48);
  const int cy = world::floor_div(static_cast<int>(std::floor(h)), kChunkSize) - 1;
  const ChunkBox box{{cx, cy, cz}, {cx + 2, cy + 2, cz + 2}};
  for (int z = -1; z <= 3; ++z)
    for (int y = -1; y <= 3; ++y)
      for (int x = -1; x <= 3; ++x)
        map.insert({cx + x, cy + y, cz + z}, gen.generate({cx + x, cy + y, cz + z}));
  return box;
}

// Random spheres added or carved, some centred exactly on chunk edges and corners.
void apply_random_changes(ChunkMap& map, const ChunkBox& box, std::mt19937& rng) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int k = 0; k < 12; ++k) {
    float c[3];
    const int lo[3] = {box.lo.x, box.lo.y, box.lo.z};
    for (int a = 0; a < 3; ++a) {
      const float span = 3.0f * kChunkSize;
      c[a] = lo[a] * kChunkSize + unit(rng) * span;
      if (k % 3 == 0)
        c[a] =
            static_cast<float>(lo[a] * kChunkSize + kChunkSize * (1 + static_cast<int>(rng() % 2)));
    }
    const float radius = 2.0f + unit(rng) * 6.0f;
    const float sign = (k % 2 == 0) ? 1.0f : -1.0f;
    for (int z = static_cast<int>(c[2] - radius) - 1; z <= static_cast<int>(c[2] + radius) + 1; ++z)
      for (int y = static_cast<int>(c[1] - radius) - 1; y <= static_cast<int>(c[1] + radius) + 1;
           ++y)
        for (int x = static_cast<int>(c[0] - radius) - 1; x <= static_cast<int>(c[0] + radius) + 1;
             ++x) {
          const float d = std::sqrt((x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) +
                                    (z - c[2]) * (z - c[2]));
          if (d > radius) continue;
          world::Chunk* chunk = map.find(world::chunk_of_voxel(x, y, z));
          if (chunk == nullptr) continue;
          const int lx = world::floor_mod(x, kChunkSize), ly = world::floor_mod(y, kChunkSize),
                    lz = world::floor_mod(z, kChunkSize);
          world::Sample s = chunk->at(lx, ly, lz);
          const float v = world::dequantize_density(s.density) + sign * (1.0f - d / radius);
          s.density = world::quantize_density(v);
          s.material = world::is_solid(s.density) ? world::Material{3} : world::kAir;
          chunk->set(lx, ly, lz, s);
        }
  }
}

void expect_chunked_equals_reference(const ChunkMap& map, const ChunkBox& box) {
  const std::vector<ChunkMesh> meshes = mesh_chunks(map, box, 2);
  const auto chunked = test::world_triangles(meshes, box);
  const auto reference = test::reference_marching_cubes(
      [&](int x, int y, int z) { return map.sample_at(x, y, z).density; },
      {box.lo.x * kChunkSize, box.lo.y * kChunkSize, box.lo.z * kChunkSize},
      {(box.hi.x + 1) * kChunkSize, (box.hi.y + 1) * kChunkSize, (box.hi.z + 1) * kChunkSize});
  ASSERT_GT(reference.size(), 100u) << "the region should contain surface";
  EXPECT_EQ(chunked.size(), reference.size());
  EXPECT_EQ(test::unmatched_triangles(chunked, reference, 1e-4f), 0u);
  EXPECT_EQ(test::unmatched_triangles(reference, chunked, 1e-4f), 0u);
}

TEST(MarchingCubes, ChunkedSurfaceEqualsReferenceOverWholeRegion) {
  std::mt19937 rng(2024);
  for (uint64_t seed : {1ull, 2ull, 3ull}) {
    ChunkMap map;
    const ChunkBox box = load_terrain_region(map, seed, rng);
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_chunked_equals_reference(map, box);
  }
}

TEST(MarchingCubes, ChunkedSurfaceEqualsReferenceAfterRandomDensityChanges) {
  std::mt19937 rng(77);
  for (uint64_t seed : {4ull, 5ull}) {
    ChunkMap map;
    const ChunkBox box = load_terrain_region(map, seed, rng);
    apply_random_changes(map, box, rng);
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_chunked_equals_reference(map, box);
  }
}

// The vertices of the edges lying in a face. A vertex at a sample is left out: an edge
// crossing the face whose fraction rounds to 0 or 1 lands there too, in one chunk only.
std::vector<std::array<uint32_t, 3>> face_vertices(const ChunkMesh& m, ChunkCoord c, int axis,
                                                   float local) {
  std::vector<std::array<uint32_t, 3>> out;
  for (const Vec3f& p : m.positions) {
    if ((&p.x)[axis] != local) continue;
    if (p.x == std::floor(p.x) && p.y == std::floor(p.y) && p.z == std::floor(p.z)) continue;
    out.push_back({std::bit_cast<uint32_t>(p.x + static_cast<float>(c.x * kChunkSize)),
                   std::bit_cast<uint32_t>(p.y + static_cast<float>(c.y * kChunkSize)),
                   std::bit_cast<uint32_t>(p.z + static_cast<float>(c.z * kChunkSize))});
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(MarchingCubes, NeighbourChunksShareBitIdenticalFaceVertices) {
  std::mt19937 rng(5);
  ChunkMap map;
  const ChunkBox box = load_terrain_region(map, 9, rng);
  apply_random_changes(map, box, rng);
  const std::vector<ChunkMesh> meshes = mesh_chunks(map, box, 2);
  size_t compared = 0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const ChunkCoord a = box.at(i);
    for (int axis = 0; axis < 3; ++axis) {
      ChunkCoord b = a;
      (axis == 0 ? b.x : axis == 1 ? b.y : b.z) += 1;
      if (b.x > box.hi.x || b.y > box.hi.y || b.z > box.hi.z) continue;
      size_t j = 0;
      while (box.at(j) != b) ++j;
      const auto from_a = face_vertices(meshes[i], a, axis, 32.0f);
      const auto from_b = face_vertices(meshes[j], b, axis, 0.0f);
      EXPECT_EQ(from_a, from_b) << "face between chunk " << i << " and " << j;
      compared += from_a.size();
    }
  }
  EXPECT_GT(compared, 0u);

  // Welded, the region's surface has open edges only on the region's outer boundary.
  const ChunkMesh welded = mesh_region(map, box, 2);
  const test::Topology topo = test::analyse(welded);
  EXPECT_EQ(topo.non_manifold_edges, 0u);
  EXPECT_EQ(topo.misoriented_edges, 0u);
  const float lo[3] = {box.lo.x * 32.0f, box.lo.y * 32.0f, box.lo.z * 32.0f};
  const float hi[3] = {(box.hi.x + 1) * 32.0f, (box.hi.y + 1) * 32.0f, (box.hi.z + 1) * 32.0f};
  for (const auto& edge : topo.open_edges) {
    bool on_outer_face = false;
    for (int a = 0; a < 3; ++a) {
      const float u = (&edge[0].x)[a], v = (&edge[1].x)[a];
      on_outer_face |= (u == lo[a] && v == lo[a]) || (u == hi[a] && v == hi[a]);
    }
    EXPECT_TRUE(on_outer_face) << "open edge inside the region (a crack) at " << edge[0].x << ","
                               << edge[0].y << "," << edge[0].z;
  }
}

TEST(MarchingCubes, SteadyStateDoesNotAllocate) {
  std::mt19937 rng(1);
  ChunkMap map;
  const ChunkBox box = load_terrain_region(map, 3, rng);
  PaddedBlock block;
  MeshScratch scratch;
  ChunkMesh mesh;
  for (size_t i = 0; i < box.count(); ++i) {  // warm up on every chunk
    gather_padded_block(map, box.at(i), block);
    mesh_chunk(block, scratch, mesh);
  }
  const size_t before = test::allocations_on_this_thread();
  size_t triangles = 0;
  for (size_t i = 0; i < box.count(); ++i) {
    gather_padded_block(map, box.at(i), block);
    mesh_chunk(block, scratch, mesh);
    triangles += mesh.triangle_count();
  }
  EXPECT_EQ(test::allocations_on_this_thread() - before, 0u);
  EXPECT_GT(triangles, 0u);
}

// A level-of-detail chunk's seams variants copy their regular triangles out of one pass
// over every cell: for any skip of whole rows and rows' end cells, the copy is what
// mesh_chunk with that skip writes.
TEST(MarchingCubes, SelectedTrianglesAreTheTrianglesMeshedWithTheSameSkip) {
  std::mt19937 rng(4);
  ChunkMap map;
  const ChunkBox box = load_terrain_region(map, 2, rng);
  PaddedBlock block;
  MeshScratch scratch;
  ChunkMesh all, skipped;
  RowTriangles rows;
  Buffer<uint32_t> selected;
  const uint64_t first = 1, last = uint64_t{1} << 31, whole = (uint64_t{1} << 32) - 1;
  const uint64_t patterns[] = {0, whole, first, last, first | last};
  size_t compared = 0;
  for (size_t i = 0; i < box.count(); ++i) {
    gather_padded_block(map, box.at(i), block);
    const bool on_corner = mesh_vertices(block, scratch, all);
    mesh_triangles_by_row(scratch, block.cells, all.positions, on_corner, all.indices, rows);
    mesh_chunk(block, scratch, skipped);
    ASSERT_EQ(all.indices, skipped.indices) << "no skip: every cell";
    for (int round = 0; round < 4; ++round) {
      CellRows skip{};
      for (uint64_t& r : skip) r = round == 0 ? 0 : patterns[rng() % 5];
      select_triangles(all.indices, rows, block.cells, skip, selected);
      mesh_chunk(block, scratch, skipped, &skip);
      ASSERT_EQ(selected, skipped.indices) << "chunk " << i << " round " << round;
      compared += skipped.triangle_count() > 0;
    }
  }
  EXPECT_GT(compared, 0u);
}

TEST(MarchingCubes, NormalsAreUnitLength) {
  std::mt19937 rng(8);
  ChunkMap map;
  const ChunkBox box = load_terrain_region(map, 6, rng);
  for (const ChunkMesh& m : mesh_chunks(map, box, 1)) {
    for (const Vec3f& n : m.normals) EXPECT_NEAR(n.x * n.x + n.y * n.y + n.z * n.z, 1.0f, 1e-4f);
    for (const Vec3f& p : m.positions) {
      EXPECT_TRUE(p.x >= 0 && p.x <= 32 && p.y >= 0 && p.y <= 32 && p.z >= 0 && p.z <= 32);
    }
  }
}

}  // namespace
}  // namespace vox::mesh
