// The surface inside one cell of a level-of-detail seam (server/world/lod_seams.hpp): a
// cube some of whose edges are split at their midpoint and some of whose faces carry their
// centre sample, with the finer level's samples at those points.
//
// Contoured with the rule that derives the marching-cubes table
// (marching_cubes_tables.cpp), applied to every polygon of the cell's boundary: a face
// with a centre is four quarter squares; any other face is a polygon of its corners and
// the midpoints of its split edges. Walking each polygon counter-clockwise seen from
// outside, the surface enters at an edge going air -> solid and leaves at the next edge
// going solid -> air, so each run of solid points is cut off on its own. The rule gives
// the same segments walked either way round, so the cell on the other side of a face (of
// this chunk, of a same-level neighbour splitting the same edges, or the finer chunk whose
// own face squares are the quarters) meets this one along the same segments. Chaining the
// segments gives closed polygons wound counter-clockwise seen from the air side. On a cell
// without splits this is the marching-cubes table's own derivation (a test checks all 256
// cases).
//
// Pure functions; any thread.
#pragma once

#include <array>
#include <cstdint>

namespace vox::mesh {

// A point of the cell's half-cell lattice, (x, y, z) each 0..2 (corners are the even
// ones): its index x + 3 y + 9 z, and its coordinates.
constexpr int seam_point(int x, int y, int z) { return x + 3 * y + 9 * z; }
constexpr std::array<int, 3> seam_point_xyz(int p) { return {p % 3, (p / 3) % 3, p / 9}; }

struct SeamCellSplits {
  uint16_t edges = 0;  // bit e: Bourke edge e is split at its midpoint
  uint8_t faces = 0;   // bit f: kCubeFaces[f] carries its centre (its edges are split too)
};

// A cut edge of the cell's boundary: two neighbouring seam points, from < to, half a cell
// (a split edge's half, or a line of a face with a centre) or a whole cell apart.
struct SeamCellEdge {
  uint8_t from = 0, to = 0;
  friend constexpr bool operator==(const SeamCellEdge&, const SeamCellEdge&) = default;
};

// The surface's closed polygons in the cell, one after another in `edges`.
struct SeamCellContour {
  static constexpr int kMaxEdges = 48;  // at most 2 segments per quarter square, 24 squares
  std::array<SeamCellEdge, kMaxEdges> edges;
  // End of polygon i in edges. Polygons have 3 sides or more, or 2 (a crease along a
  // split edge); each uses segments of at least two faces: at most 16 of them.
  std::array<uint8_t, kMaxEdges / 2> polygon_end;
  int polygons = 0;
  int edge_count() const { return polygons == 0 ? 0 : polygon_end[polygons - 1]; }
};

// Bit p of `solid` set when seam point p is solid. Reads the corners, the midpoints of
// split edges and the centres of faces with centres.
void contour_seam_cell(SeamCellSplits splits, uint32_t solid, SeamCellContour& out);

}  // namespace vox::mesh
