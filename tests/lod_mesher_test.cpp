// Level-of-detail meshes with seams (server/mesh/lod_mesher.hpp, seam_cell.hpp): the seam
// cell rule is the marching-cubes table's own, and chunks of levels 0, 1 and 2 laid out as
// a client sees them make one closed surface.
#include "server/mesh/lod_mesher.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <functional>
#include <map>
#include <random>
#include <set>

#include "proto/mesh_codec.hpp"
#include "server/mesh/marching_cubes_tables.hpp"
#include "server/world/gradient_noise.hpp"
#include "server/world/terrain_sampler.hpp"
#include "tests/mesh_test_util.hpp"

namespace vox::mesh {
namespace {

using world::LodChunk;
using world::LodLayout;
using world::LodSeams;

class FieldSampler : public world::PointSampler {
 public:
  explicit FieldSampler(std::function<float(float, float, float)> field)
      : field_(std::move(field)) {}
  void sample_grid(const std::array<int32_t, 3>& origin, int32_t step, const std::array<int, 3>& n,
                   world::Sample* out) const override {
    for (int k = 0; k < n[2]; ++k)
      for (int j = 0; j < n[1]; ++j)
        for (int i = 0; i < n[0]; ++i, ++out) {
          const float d = field_(static_cast<float>(origin[0] + step * i),
                                 static_cast<float>(origin[1] + step * j),
                                 static_cast<float>(origin[2] + step * k));
          out->density = world::quantize_density(d);
          out->material = world::is_solid(out->density) ? 1 : 0;
        }
  }

 private:
  std::function<float(float, float, float)> field_;
};

// The Bourke edge joining two corner seam points.
int bourke_edge(SeamCellEdge e) {
  for (int k = 0; k < 12; ++k) {
    const auto& a = kCubeCorner[kEdgeCorners[k][0]];
    const auto& b = kCubeCorner[kEdgeCorners[k][1]];
    const int pa = seam_point(2 * a[0], 2 * a[1], 2 * a[2]),
              pb = seam_point(2 * b[0], 2 * b[1], 2 * b[2]);
    if ((pa == e.from && pb == e.to) || (pa == e.to && pb == e.from)) return k;
  }
  return -1;
}

TEST(SeamCell, WithoutSplitsItGivesTheMarchingCubesTablePolygons) {
  for (int c = 1; c < 255; ++c) {
    uint32_t solid = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const auto& p = kCubeCorner[corner];
      if ((c >> corner) & 1) solid |= 1u << seam_point(2 * p[0], 2 * p[1], 2 * p[2]);
    }
    SeamCellContour contour;
    contour_seam_cell({}, solid, contour);
    // The directed polygon sides, and the table triangles' sides used once (a fan's inner
    // sides are used twice, once each way).
    std::set<std::pair<int, int>> sides, table_sides;
    int begin = 0;
    for (int k = 0; k < contour.polygons; ++k) {
      const int end = contour.polygon_end[k];
      for (int i = begin; i < end; ++i) {
        const int next = i + 1 == end ? begin : i + 1;
        sides.insert({bourke_edge(contour.edges[i]), bourke_edge(contour.edges[next])});
      }
      begin = end;
    }
    std::map<std::pair<int, int>, int> uses;
    for (int t = 0; triTable[c][t] >= 0; t += 3)
      for (int i = 0; i < 3; ++i) ++uses[{triTable[c][t + i], triTable[c][t + (i + 1) % 3]}];
    for (const auto& [side, n] : uses)
      if (!uses.contains({side.second, side.first})) table_sides.insert(side);
    EXPECT_EQ(sides, table_sides) << "case " << c;
  }
}

TEST(SeamCell, EveryCutEdgeStartsOneSegmentAndEndsOne) {
  // All points solid or air at random, every split: each cut edge of the boundary is in
  // exactly one polygon, so polygons of neighbouring cells can share it.
  uint32_t state = 12345;
  for (int trial = 0; trial < 20000; ++trial) {
    state = state * 1664525u + 1013904223u;
    const uint32_t solid = state & ((1u << 27) - 1);
    state = state * 1664525u + 1013904223u;
    const SeamCellSplits splits{static_cast<uint16_t>(state & 0xfff),
                                static_cast<uint8_t>((state >> 12) & 0x3f)};
    SeamCellContour contour;
    contour_seam_cell(splits, solid, contour);
    std::set<std::pair<int, int>> seen;
    for (int i = 0; i < contour.edge_count(); ++i) {
      const SeamCellEdge e = contour.edges[i];
      EXPECT_TRUE(seen.insert({e.from, e.to}).second);
      EXPECT_NE(((solid >> e.from) & 1), ((solid >> e.to) & 1)) << "an edge the surface cuts";
    }
    // A polygon has three sides or more, or it is the two halves of one split edge whose
    // midpoint alone differs from the points around it on both faces: a crease along the
    // edge, with no area (the cells across those faces carry the surface there).
    int begin = 0;
    for (int k = 0; k < contour.polygons; ++k) {
      const int n = contour.polygon_end[k] - begin;
      EXPECT_GE(n, 2);
      if (n == 2) {
        const SeamCellEdge a = contour.edges[begin], b = contour.edges[begin + 1];
        // Points of one line: from < to, so a's upper end is b's lower end or the reverse.
        const bool a_below = a.to == b.from, b_below = b.to == a.from;
        ASSERT_TRUE(a_below || b_below) << "halves of one edge";
        const int mid = a_below ? a.to : a.from;
        const int lo = a_below ? a.from : b.from, hi = a_below ? b.to : a.to;
        EXPECT_EQ(mid - lo, hi - mid) << "on one line, either side of the midpoint";
      }
      begin = contour.polygon_end[k];
    }
  }
}

// The seam cells come from rows and end bits; they are the cells with a split edge.
TEST(SeamCell, SeamCellRowsAreTheCellsWithASplitEdge) {
  std::mt19937 rng(6);
  CellRows rows{};
  for (int trial = 0; trial < 300; ++trial) {
    const LodSeams seams =
        world::normalized({static_cast<uint8_t>(trial < 64 ? trial : rng() % 64),
                           static_cast<uint16_t>(trial < 64 ? 0 : rng() % 4096)});
    seam_cell_rows(seams, rows);
    for (int z = 0; z < 32; ++z)
      for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x)
          ASSERT_EQ((rows[detail::row_of(y, z)] >> x) & 1,
                    seam_cell_splits(seams, x, y, z).edges != 0 ? 1u : 0u)
              << "seams " << int{seams.faces} << "/" << seams.edges << " cell " << x << " " << y
              << " " << z;
  }
}

struct LodView {
  ChunkMesh combined;                                    // world positions
  std::map<int, std::vector<Vec3f>> vertices_per_level;  // world positions, used ones
  std::map<int, size_t> triangles_per_level;
  size_t seam_chunks_with_surface = 0;
};

// All chunks of the layout meshed with their seams (or, for the control, without).
LodView mesh_layout(const LodLayout& layout, const world::PointSampler& sampler,
                    bool with_seams = true) {
  LodView view;
  LodBlock block;
  LodScratch scratch;
  ChunkMesh mesh;
  for (const LodChunk& c : layout.chunks()) {
    const LodSeams seams = with_seams ? layout.seams(c) : LodSeams{};
    gather_lod_block(sampler, c, seams, block);
    mesh_lod_chunk(block, scratch, mesh);
    if (mesh.empty()) continue;
    view.triangles_per_level[c.level] += mesh.triangle_count();
    view.seam_chunks_with_surface += !seams.empty();
    const auto lo = c.lo();
    const float scale = static_cast<float>(int64_t{1} << c.level);
    const auto base = static_cast<uint32_t>(view.combined.positions.size());
    for (const Vec3f& p : mesh.positions) {
      view.combined.positions.push_back({static_cast<float>(lo[0]) + p.x * scale,
                                         static_cast<float>(lo[1]) + p.y * scale,
                                         static_cast<float>(lo[2]) + p.z * scale});
    }
    for (uint32_t i : mesh.indices) view.combined.indices.push_back(base + i);
    for (uint32_t i : mesh.indices)
      view.vertices_per_level[c.level].push_back(view.combined.positions[base + i]);
  }
  return view;
}

TEST(LodMesher, ASphereAcrossChunksOfLevelsZeroOneAndTwoIsOneClosedSurface) {
  LodLayout layout({.levels = 3, .top_radius = 1, .split_distance = 1.0});
  layout.update({20.5, 12.25, 30.75});
  const float cx = 61.3f, cy = 40.6f, cz = 75.8f, r = 118.0f;
  const FieldSampler sampler([&](float x, float y, float z) {
    return (r - std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz))) * 0.05f;
  });
  const LodView view = mesh_layout(layout, sampler);
  for (int level = 0; level < 3; ++level) EXPECT_GT(view.triangles_per_level.count(level), 0u);
  EXPECT_GT(view.seam_chunks_with_surface, 0u);
  const test::Topology t = test::analyse(view.combined);
  test::expect_closed_manifold(t);
  EXPECT_EQ(t.components, 1u);
  // A level-k surface lies within 2^k voxels of the sphere (the level-0 surface).
  for (const auto& [level, vertices] : view.vertices_per_level) {
    for (const Vec3f& v : vertices) {
      const float d =
          std::sqrt((v.x - cx) * (v.x - cx) + (v.y - cy) * (v.y - cy) + (v.z - cz) * (v.z - cz));
      ASSERT_LE(std::abs(d - r), static_cast<float>(1 << level)) << "level " << level;
    }
  }
  // The control: without seams the levels leave cracks, which the check sees.
  EXPECT_GT(test::analyse(mesh_layout(layout, sampler, false).combined).boundary_edges, 100u);
}

// Metaballs (seed 004's field) around random eyes: every layout puts the seams (faces,
// edges only, corners where three levels meet) somewhere else on the surfaces.
TEST(LodMesher, MetaballsAroundRandomEyesAreClosed) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> eye_at(-40.0, 40.0);
  size_t seam_chunks = 0;
  for (int trial = 0; trial < 4; ++trial) {
    LodLayout layout({.levels = 3, .top_radius = 1, .split_distance = 1.0});
    layout.update({eye_at(rng), eye_at(rng), eye_at(rng)});
    struct Ball {
      float x, y, z, s;
    };
    // 60-110 voxels from the eyes, where levels 0, 1 and 2 meet; inside every layout.
    const Ball balls[] = {{-88.3f, 10.2f, 5.1f, 625.0f},
                          {84.6f, -20.1f, 10.4f, 500.0f},
                          {2.2f, 88.7f, -30.9f, 400.0f},
                          {-40.4f, -79.6f, 69.3f, 300.0f},
                          {-60.1f, 30.3f, 40.2f, 350.0f}};
    const FieldSampler sampler([&](float x, float y, float z) {
      float f = 0;
      for (const Ball& b : balls)
        f += b.s / ((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y) + (z - b.z) * (z - b.z) + 1.0f);
      return std::min(f - 1.0f, 1.0f);
    });
    const LodView view = mesh_layout(layout, sampler);
    seam_chunks += view.seam_chunks_with_surface;
    const test::Topology t = test::analyse(view.combined);
    test::expect_closed_manifold(t);
  }
  EXPECT_GT(seam_chunks, 8u);
}

// Many small shapes, ambiguous cells and pockets on the seams: a noise field cut off by a
// ball inside the layout, so that the whole is closed.
TEST(LodMesher, ANoisyFieldAcrossLevelsIsClosed) {
  LodLayout layout({.levels = 3, .top_radius = 1, .split_distance = 1.0});
  layout.update({-10.5, 20.25, 5.75});  // [-256, 128) x [-128, 256) x [-128, 256)
  const world::GradientNoise noise(11);
  const FieldSampler sampler([&](float x, float y, float z) {
    const float ball =
        110.0f - std::sqrt((x + 60) * (x + 60) + (y - 60) * (y - 60) + (z - 60) * (z - 60));
    return std::min(ball * 0.05f, noise.noise3(x / 9.0f, y / 7.0f, z / 11.0f) + 0.1f);
  });
  const LodView view = mesh_layout(layout, sampler);
  for (int level = 0; level < 2; ++level) EXPECT_GT(view.triangles_per_level.count(level), 0u);
  EXPECT_GT(view.seam_chunks_with_surface, 10u);
  const test::Topology t = test::analyse(view.combined);
  EXPECT_GT(t.components, 50u);
  EXPECT_EQ(t.boundary_edges, 0u);
  EXPECT_EQ(t.misoriented_edges, 0u);
  // Vertices rounded onto a sample (fraction 0 or 1) can meet several others there, at
  // level 0 as on any level; anywhere else an edge is in two triangles.
  for (const auto& e : t.crowded_edges) {
    auto on_sample = [](const Vec3f& p) {
      return p.x == std::floor(p.x) && p.y == std::floor(p.y) && p.z == std::floor(p.z);
    };
    EXPECT_TRUE(on_sample(e[0]) || on_sample(e[1]))
        << "(" << e[0].x << ", " << e[0].y << ", " << e[0].z << ") - (" << e[1].x << ", " << e[1].y
        << ", " << e[1].z << ")";
  }
}

// select_triangles (marching_cubes.hpp) copies a variant's regular triangles row by row:
// it takes seam cell rows to be empty, whole, or a row's end cells only.
TEST(LodMesher, SeamCellRowsAreEmptyWholeOrARowsEndCells) {
  const uint64_t whole = (uint64_t{1} << world::kChunkSize) - 1, ends = 1 | (uint64_t{1} << 31);
  std::mt19937 rng(11);
  CellRows rows;
  for (int faces = 0; faces < 64; ++faces) {
    for (int round = 0; round < 16; ++round) {
      const LodSeams seams =
          world::normalized({static_cast<uint8_t>(faces),
                             static_cast<uint16_t>(round < 12 ? 1u << round : rng() & 0xFFF)});
      seam_cell_rows(seams, rows);
      for (const uint64_t r : rows)
        ASSERT_TRUE(r == 0 || r == whole || (r & ~ends) == 0)
            << "faces " << faces << " edges " << seams.edges;
    }
  }
}

// The pipeline gathers a chunk's samples once for every seams variant wanted, makes the
// regular vertices once and meshes each variant from them: a variant made that way, after
// other variants, is the mesh (and the encoding) of a block gathered and meshed for its
// own seams alone.
TEST(LodMesher, AVariantMeshedFromABlockGatheredForMoreSeamsIsTheSameMesh) {
  const world::GradientNoise noise(5);
  const FieldSampler sampler([&](float x, float y, float z) {
    return noise.noise3(x / 13.0f, y / 9.0f, z / 11.0f) + 0.05f * (40.0f - y) / 40.0f;
  });
  const LodChunk c{1, {0, 0, 0}};
  LodBlock all;
  gather_lod_block(sampler, c, {.faces = 63, .edges = 0xFFF}, all);
  LodScratch sa;
  mesh_lod_vertices(all, sa);
  proto::CodecScratch shared_codec;  // the variants' rows and vertex planes written once
  std::mt19937 rng(3);
  for (int round = 0; round < 12; ++round) {
    const LodSeams seams =
        world::normalized({.faces = static_cast<uint8_t>(rng() & 63),
                           .edges = static_cast<uint16_t>(round % 3 == 0 ? rng() & 0xFFF : 0)});
    LodBlock own;
    gather_lod_block(sampler, c, seams, own);
    all.seams = seams;
    LodScratch so;
    ChunkMesh ma, mo;
    mesh_lod_variant(all, sa, ma);
    mesh_lod_chunk(own, so, mo);
    proto::CodecScratch codec;
    proto::Bytes ea, eo;
    proto::encode_lod_mesh(ma, sa, shared_codec, ea, 1);
    proto::encode_lod_mesh(mo, so, codec, eo);
    EXPECT_EQ(ea, eo) << "seams " << int{seams.faces} << "/" << seams.edges;
    ASSERT_GT(mo.triangle_count(), 0u);
    EXPECT_TRUE(
        std::equal(ma.indices.begin(), ma.indices.end(), mo.indices.begin(), mo.indices.end()))
        << "seams " << int{seams.faces} << "/" << seams.edges;
    ASSERT_EQ(ma.vertex_count(), mo.vertex_count());
    for (size_t i = 0; i < ma.vertex_count(); ++i) {
      ASSERT_EQ(ma.positions[i], mo.positions[i]);
      ASSERT_EQ(ma.normals[i], mo.normals[i]);
      ASSERT_EQ(ma.materials[i], mo.materials[i]);
    }
  }
}

// The one edge-vertex rule (edge_vertex.hpp) at work: where a level-1 chunk's split face
// meets level-0 chunks, its seam vertices on that face are the level-0 mesher's vertices
// there, position, normal and material alike, bit for bit.
TEST(LodMesher, ASplitFacesSeamVerticesAreTheFinerChunksVerticesBitForBit) {
  const world::GradientNoise noise(9);
  const FieldSampler field([&](float x, float y, float z) {
    return noise.noise3(x / 7.0f, y / 5.0f, z / 6.0f) + 0.1f * (30.0f - y) / 30.0f;
  });
  // Materials that change from voxel to voxel, so that taking the wrong end shows.
  class MaterialSampler : public world::PointSampler {
   public:
    explicit MaterialSampler(const world::PointSampler& inner) : inner_(inner) {}
    void sample_grid(const std::array<int32_t, 3>& origin, int32_t step,
                     const std::array<int, 3>& n, world::Sample* out) const override {
      inner_.sample_grid(origin, step, n, out);
      for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
          for (int i = 0; i < n[0]; ++i, ++out) {
            const int32_t sum = origin[0] + origin[1] + origin[2] + step * (i + j + k);
            if (out->material != world::kAir)
              out->material = static_cast<world::Material>(1 + ((sum % 5) + 5) % 5);
          }
    }

   private:
    const world::PointSampler& inner_;
  };
  const MaterialSampler sampler(field);
  struct FaceVertex {
    std::array<float, 3> p, n;
    int material;
    auto operator<=>(const FaceVertex&) const = default;
  };
  // Vertices of `mesh` (chunk `c`) on edges along y or z whose world x is 0: those in the
  // face plane (an edge along x may end on it too, from one side only). `axis_of(i)`.
  const auto on_face = [](const LodChunk& c, const ChunkMesh& mesh, auto axis_of,
                          std::set<FaceVertex>& out) {
    const auto lo = c.lo();
    const float scale = static_cast<float>(int64_t{1} << c.level);
    for (size_t i = 0; i < mesh.vertex_count(); ++i) {
      const int axis = axis_of(i);
      if (axis <= 0) continue;  // along x, or not a seam vertex
      const Vec3f& p = mesh.positions[i];
      const std::array<float, 3> w{static_cast<float>(lo[0]) + p.x * scale,
                                   static_cast<float>(lo[1]) + p.y * scale,
                                   static_cast<float>(lo[2]) + p.z * scale};
      if (w[0] != 0.0f) continue;
      const Vec3f& n = mesh.normals[i];
      out.insert({w, {n.x, n.y, n.z}, mesh.materials[i]});
    }
  };
  LodBlock block;
  LodScratch scratch;
  ChunkMesh mesh;
  std::set<FaceVertex> coarse, fine;
  const LodChunk big{1, {0, 0, 0}};
  gather_lod_block(sampler, big, {world::kMinusX, 0}, block);
  mesh_lod_chunk(block, scratch, mesh);
  on_face(
      big, mesh,
      [&](size_t i) {
        return i < scratch.regular_vertices
                   ? -1
                   : scratch.seam_vertices[i - scratch.regular_vertices].axis;
      },
      coarse);
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 2; ++y) {
      const LodChunk small{0, {-1, y, z}};
      gather_lod_block(sampler, small, {}, block);
      mesh_lod_chunk(block, scratch, mesh);
      // The marching-cubes numbering (marching_cubes.hpp): by row, then axis, then x.
      std::vector<int> axis(mesh.vertex_count(), -1);
      for (int r = 0; r < kRows; ++r)
        for (int a = 0; a < 3; ++a) {
          const uint32_t first = scratch.mc.first_vertex[a][r];
          for (int k = 0; k < std::popcount(scratch.mc.cut[a][r]); ++k) axis[first + k] = a;
        }
      on_face(
          small, mesh, [&](size_t i) { return axis[i]; }, fine);
    }
  ASSERT_GT(fine.size(), 50u);
  EXPECT_EQ(coarse, fine);
}

// Terrain is open where the layout ends; everywhere else, and so on every seam, the chunks
// of different levels meet edge to edge.
TEST(LodMesher, TerrainAcrossFourLevelsIsOpenOnlyAtTheLayoutsOuterFaces) {
  const world::TerrainGenerator generator(3);
  const world::TerrainSampler sampler(generator);
  LodLayout layout({.levels = 4, .top_radius = 1, .split_distance = 1.0});
  const std::array<double, 3> eye{40.5, generator.height_at(40, -20) + 2.0, -20.5};
  layout.update(eye);
  const LodView view = mesh_layout(layout, sampler);
  // (The level-3 chunks of this layout lie above or below the surface.)
  for (int level = 0; level < 3; ++level) EXPECT_GT(view.triangles_per_level.count(level), 0u);
  EXPECT_GT(view.seam_chunks_with_surface, 10u);
  const test::Topology t = test::analyse(view.combined);
  EXPECT_EQ(t.non_manifold_edges, 0u);
  EXPECT_EQ(t.misoriented_edges, 0u);
  // The layout's box: the top-level chunks around the eye's.
  const float top = 32.0f * 8.0f;
  std::array<float, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = (std::floor(static_cast<float>(eye[a]) / top) - 1.0f) * top;
    hi[a] = lo[a] + 3.0f * top;
  }
  size_t inner = 0;
  for (const auto& e : t.open_edges) {
    bool outer = false;
    for (int a = 0; a < 3; ++a) {
      const float u = (&e[0].x)[a], v = (&e[1].x)[a];
      outer |= (u == lo[a] && v == lo[a]) || (u == hi[a] && v == hi[a]);
    }
    inner += !outer;
  }
  EXPECT_GT(t.boundary_edges, 0u);
  EXPECT_EQ(inner, 0u) << "open edges inside the layout";

  // A level-k surface lies within 2^k voxels of the level-0 one: the generator's samples
  // around each checked vertex, 2^k voxels either way, are not all solid or all air.
  for (const auto& [level, vertices] : view.vertices_per_level) {
    const int reach = 1 << level;
    for (size_t i = 0; i < vertices.size(); i += vertices.size() / 200 + 1) {
      const Vec3f v = vertices[i];
      bool solid = false, air = false;
      for (int z = static_cast<int>(std::ceil(v.z)) - reach; z <= std::floor(v.z) + reach; ++z)
        for (int y = static_cast<int>(std::ceil(v.y)) - reach; y <= std::floor(v.y) + reach; ++y)
          for (int x = static_cast<int>(std::ceil(v.x)) - reach; x <= std::floor(v.x) + reach;
               ++x) {
            (world::is_solid(generator.sample_at(x, y, z).density) ? solid : air) = true;
          }
      EXPECT_TRUE(solid && air) << "level " << level << " vertex (" << v.x << ", " << v.y << ", "
                                << v.z << ")";
    }
  }
}

}  // namespace
}  // namespace vox::mesh
