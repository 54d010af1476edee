// Test helpers: a plain per-cell reference marching cubes straight from the tables (no
// chunks, no vertex sharing), world-space triangle soups, and mesh topology checks.
#pragma once

#include <array>
#include <functional>
#include <vector>

#include "server/mesh/chunk_mesh.hpp"
#include "server/mesh/region_mesher.hpp"
#include "server/world/chunk_map.hpp"

namespace vox::test {

using Triangle = std::array<mesh::Vec3f, 3>;

// Reference marching cubes over the cells [lo, hi) (world voxel coordinates), reading
// samples through `density`. Edge fractions are rounded to 1/1024 and triangles of zero
// area at those positions dropped, as the mesher does.
std::vector<Triangle> reference_marching_cubes(
    const std::function<world::Density(int, int, int)>& density, std::array<int, 3> lo,
    std::array<int, 3> hi);

// World-space triangles of chunk meshes (chunk-local positions + origin).
std::vector<Triangle> world_triangles(const std::vector<mesh::ChunkMesh>& meshes,
                                      const mesh::ChunkBox& box);
std::vector<Triangle> world_triangles(const mesh::ChunkMesh& welded);

// Number of triangles of `a` with no counterpart in `b` (same winding, every vertex
// within `tolerance`); each triangle of b matches at most once.
size_t unmatched_triangles(const std::vector<Triangle>& a, const std::vector<Triangle>& b,
                           float tolerance);

struct Topology {
  size_t vertices = 0, edges = 0, faces = 0;
  size_t components = 0;
  size_t boundary_edges = 0;                              // edges used by one triangle
  size_t non_manifold_edges = 0;                          // edges used by more than two triangles
  size_t misoriented_edges = 0;                           // edges used twice in the same direction
  std::vector<std::array<mesh::Vec3f, 2>> open_edges;     // the boundary edges' end points
  std::vector<std::array<mesh::Vec3f, 2>> crowded_edges;  // the non-manifold edges' ends
  double area = 0, volume = 0;  // volume by the divergence theorem (> 0: outward normals)
  long euler() const {
    return static_cast<long>(vertices) - static_cast<long>(edges) + static_cast<long>(faces);
  }
};
// Vertices are identified by exact position, so coincident duplicates count as one.
Topology analyse(const mesh::ChunkMesh& welded);
// gtest expectations: some faces, every edge in two triangles wound opposite ways, genus-0
// components, outward normals; the first open edges are named.
void expect_closed_manifold(const Topology& t);

// Fills the box's chunks (plus a one-chunk margin) from a field in world coordinates.
void fill_from_field(world::ChunkMap& map, const mesh::ChunkBox& box,
                     const std::function<float(float, float, float)>& field,
                     world::Material material = 1);

}  // namespace vox::test
