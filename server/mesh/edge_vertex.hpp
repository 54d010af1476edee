// The one rule for a marching-cubes vertex on a cut edge, shared by the level-0 mesher
// (marching_cubes.cpp) and the level-of-detail seam mesher (lod_mesher.cpp): where a finer
// chunk meets a coarser one, both make the same vertex from the same samples, and the seam
// closes only while they compute it bit for bit alike. Linear interpolation of the edge
// (Lorensen & Cline), its fraction rounded to the wire's step; the normal interpolates the
// central-difference gradients of the edge's ends.
#pragma once

#include <cmath>
#include <cstdint>

#include "server/mesh/chunk_mesh.hpp"
#include "server/world/sample.hpp"

namespace vox::mesh {

// Vertex positions are rounded to 1/kFractionSteps of an edge, the step of the wire
// encoding (docs/PROTOCOL.md §2.4), so that the server's meshes equal the decoded ones.
inline constexpr int kFractionSteps = 1024;

// Offsets of the next sample along x, y and z in a grid of densities.
using GridStrides = int[3];

// The density gradient at sample i, by central differences (the grid holds i's neighbours).
inline Vec3f gradient(const world::Density* d, int i, const GridStrides& stride) {
  return {static_cast<float>(d[i + stride[0]] - d[i - stride[0]]),
          static_cast<float>(d[i + stride[1]] - d[i - stride[1]]),
          static_cast<float>(d[i + stride[2]] - d[i - stride[2]])};
}

// Bourke edge (marching_cubes_tables.hpp) -> its axis and the offset of its lower sample in
// the cell.
struct EdgeSlot {
  int8_t axis, dx, dy, dz;
};
inline constexpr EdgeSlot kEdgeSlot[12] = {
    {0, 0, 0, 0}, {1, 1, 0, 0}, {0, 0, 1, 0}, {1, 0, 0, 0}, {0, 0, 0, 1}, {1, 1, 0, 1},
    {0, 0, 1, 1}, {1, 0, 0, 1}, {2, 0, 0, 0}, {2, 1, 0, 0}, {2, 1, 1, 0}, {2, 0, 1, 0},
};

// How far along its edge from the lower sample a vertex of `fraction` lies, in voxels: the
// position every mesher (and a raycast) gives it.
inline float edge_offset(int fraction) {
  return static_cast<float>(fraction) * (1.0f / kFractionSteps);
}

struct EdgeVertex {
  int fraction;  // along the edge from i0, in 1/kFractionSteps (0..kFractionSteps)
  Vec3f normal;  // unit length, towards air
  world::Material material;
};

// The vertex on the cut edge from sample i0 to i0 + stride[axis]; a sample is solid when
// its density is above `floor`. Where the field is flat the normal points along the edge,
// from its solid end to its air end; the material is the solid end's.
inline EdgeVertex edge_vertex(const world::Density* d, const world::Material* m, int i0, int axis,
                              const GridStrides& stride, world::Density floor) {
  const int i1 = i0 + stride[axis];
  const int d0 = d[i0], d1 = d[i1];
  const float t = static_cast<float>(d0) / static_cast<float>(d0 - d1);
  EdgeVertex v;
  v.fraction = static_cast<int>(t * kFractionSteps + 0.5f);
  const Vec3f g0 = gradient(d, i0, stride), g1 = gradient(d, i1, stride);
  Vec3f n{-(g0.x + t * (g1.x - g0.x)), -(g0.y + t * (g1.y - g0.y)), -(g0.z + t * (g1.z - g0.z))};
  const float len2 = n.x * n.x + n.y * n.y + n.z * n.z;
  if (len2 > 0.0f) {
    const float inv = 1.0f / std::sqrt(len2);
    n = {n.x * inv, n.y * inv, n.z * inv};
  } else {
    n = {};
    (&n.x)[axis] = d0 > floor ? 1.0f : -1.0f;
  }
  v.normal = n;
  v.material = d0 > floor ? m[i0] : m[i1];
  return v;
}

}  // namespace vox::mesh
