#include "server/mesh/seam_cell.hpp"

#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::mesh {
namespace {

constexpr int corner_point(int corner) {
  return seam_point(2 * kCubeCorner[corner][0], 2 * kCubeCorner[corner][1],
                    2 * kCubeCorner[corner][2]);
}

constexpr int midpoint(int p, int q) {
  const auto a = seam_point_xyz(p), b = seam_point_xyz(q);
  return seam_point((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2);
}

constexpr int edge_between(int corner_a, int corner_b) {
  for (int e = 0; e < 12; ++e) {
    if ((kEdgeCorners[e][0] == corner_a && kEdgeCorners[e][1] == corner_b) ||
        (kEdgeCorners[e][0] == corner_b && kEdgeCorners[e][1] == corner_a))
      return e;
  }
  return -1;
}

// The cut edges met so far and, for each, the edge the surface goes on to.
class SegmentGraph {
 public:
  int id(int p, int q) {
    const SeamCellEdge e{static_cast<uint8_t>(p < q ? p : q), static_cast<uint8_t>(p < q ? q : p)};
    for (int i = 0; i < count_; ++i)
      if (edges_[i] == e) return i;
    edges_[count_] = e;
    next_[count_] = -1;
    return count_++;
  }
  void link(int from, int to) { next_[from] = static_cast<int8_t>(to); }

  // Applies the rule to one polygon of the boundary, points counter-clockwise seen from
  // outside the cell.
  void add_polygon(const int* points, int n, uint32_t solid) {
    auto is_solid = [&](int i) { return ((solid >> points[i % n]) & 1) != 0; };
    for (int i = 0; i < n; ++i) {
      if (is_solid(i) || !is_solid(i + 1)) continue;  // need air -> solid
      for (int k = 1; k < n; ++k) {
        const int j = (i + k) % n;
        if (is_solid(j) && !is_solid(j + 1)) {
          link(id(points[i], points[(i + 1) % n]), id(points[j], points[(j + 1) % n]));
          break;
        }
      }
    }
  }

  void chain(SeamCellContour& out) const {
    bool used[SeamCellContour::kMaxEdges] = {};
    int written = 0;
    out.polygons = 0;
    for (int start = 0; start < count_; ++start) {
      if (next_[start] < 0 || used[start]) continue;
      for (int e = start; e >= 0 && !used[e]; e = next_[e]) {
        used[e] = true;
        out.edges[written++] = edges_[e];
      }
      out.polygon_end[out.polygons++] = static_cast<uint8_t>(written);
    }
  }

 private:
  std::array<SeamCellEdge, SeamCellContour::kMaxEdges> edges_{};
  std::array<int8_t, SeamCellContour::kMaxEdges> next_{};
  int count_ = 0;
};

}  // namespace

void contour_seam_cell(SeamCellSplits splits, uint32_t solid, SeamCellContour& out) {
  for (int f = 0; f < 6; ++f) {  // a face's centre splits its edges
    if (((splits.faces >> f) & 1) == 0) continue;
    for (int i = 0; i < 4; ++i)
      splits.edges |=
          static_cast<uint16_t>(1u << edge_between(kCubeFaces[f][i], kCubeFaces[f][(i + 1) % 4]));
  }
  SegmentGraph graph;
  for (int f = 0; f < 6; ++f) {
    int corner[4];
    for (int i = 0; i < 4; ++i) corner[i] = corner_point(kCubeFaces[f][i]);
    int mid[4];  // mid[i]: midpoint of the side from corner i to corner i + 1
    for (int i = 0; i < 4; ++i) mid[i] = midpoint(corner[i], corner[(i + 1) % 4]);
    if ((splits.faces >> f) & 1) {
      const int centre = midpoint(corner[0], corner[2]);
      for (int i = 0; i < 4; ++i) {
        const int quarter[4] = {corner[i], mid[i], centre, mid[(i + 3) % 4]};
        graph.add_polygon(quarter, 4, solid);
      }
      continue;
    }
    int polygon[8];
    int n = 0;
    for (int i = 0; i < 4; ++i) {
      polygon[n++] = corner[i];
      const int e = edge_between(kCubeFaces[f][i], kCubeFaces[f][(i + 1) % 4]);
      if ((splits.edges >> e) & 1) polygon[n++] = mid[i];
    }
    graph.add_polygon(polygon, n, solid);
  }
  graph.chain(out);
}

}  // namespace vox::mesh
