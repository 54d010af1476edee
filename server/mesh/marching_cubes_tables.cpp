// Derivation of the marching-cubes tables (layout of Bourke 1994 / Bloyd).
//
// For each of the 256 corner sign cases the surface inside the cube is the boundary of
// the solid corners. On each face, walked counter-clockwise as seen from outside the
// cube, the surface enters at an edge going air -> solid and leaves at the next edge
// going solid -> air. On an ambiguous face (solid and air corners alternating) this pairs
// each solid corner with its own two edges: solid corners that touch only diagonally are
// kept apart. Both cubes sharing a face see the same corners and apply the same rule, so
// the surface has no holes. Chaining the face segments gives closed polygons, wound
// counter-clockwise seen from the air side; each polygon becomes a triangle fan from the
// apex whose thinnest triangle (with vertices at the edge midpoints) is the widest, so no
// fan triangle is degenerate, and none lies flat in a face of the cube (the cell across
// the face could have the same triangle, wound the other way: a fin of zero thickness,
// four triangles on one edge).
#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::mesh {
namespace {

constexpr int edge_between(int a, int b) {
  for (int e = 0; e < 12; ++e) {
    if ((kEdgeCorners[e][0] == a && kEdgeCorners[e][1] == b) ||
        (kEdgeCorners[e][0] == b && kEdgeCorners[e][1] == a)) {
      return e;
    }
  }
  return -1;
}

// Twice the squared area of the triangle between the midpoints of three edges, x4^2.
constexpr int fan_triangle_weight(int e0, int e1, int e2) {
  int p[3][3] = {};
  const int edges[3] = {e0, e1, e2};
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 3; ++j)
      p[k][j] =
          kCubeCorner[kEdgeCorners[edges[k]][0]][j] + kCubeCorner[kEdgeCorners[edges[k]][1]][j];
  const int u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
  const int w[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
  const int n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                    u[0] * w[1] - u[1] * w[0]};
  return n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
}

// Whether the three edges lie on one face of the cube: a fan triangle there would lie flat
// in the face, and the cell across it can have the same one, wound the other way.
constexpr bool on_one_face(int e0, int e1, int e2) {
  for (const auto& face : kCubeFaces) {
    int on = 0;
    for (int i = 0; i < 4; ++i) {
      const int e = edge_between(face[i], face[(i + 1) % 4]);
      on += (e == e0) + (e == e1) + (e == e2);
    }
    if (on == 3) return true;
  }
  return false;
}

constexpr std::array<uint16_t, 256> make_edge_table() {
  std::array<uint16_t, 256> table{};
  for (int c = 0; c < 256; ++c) {
    for (int e = 0; e < 12; ++e) {
      const bool a = (c >> kEdgeCorners[e][0]) & 1, b = (c >> kEdgeCorners[e][1]) & 1;
      if (a != b) table[c] = static_cast<uint16_t>(table[c] | (1u << e));
    }
  }
  return table;
}

constexpr std::array<int8_t, 16> make_tri_row(int c) {
  auto solid = [c](int corner) { return ((c >> corner) & 1) != 0; };
  int next[12] = {-1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};
  for (const auto& face : kCubeFaces) {
    for (int i = 0; i < 4; ++i) {
      if (solid(face[i]) || !solid(face[(i + 1) % 4])) continue;  // need air -> solid
      for (int k = 1; k < 4; ++k) {
        const int j = (i + k) % 4;
        if (solid(face[j]) && !solid(face[(j + 1) % 4])) {
          next[edge_between(face[i], face[(i + 1) % 4])] = edge_between(face[j], face[(j + 1) % 4]);
          break;
        }
      }
    }
  }
  std::array<int8_t, 16> row{};
  for (auto& v : row) v = -1;
  int out = 0;
  bool used[12] = {};
  for (int start = 0; start < 12; ++start) {
    if (next[start] < 0 || used[start]) continue;
    int polygon[12] = {};
    int n = 0;
    for (int e = start; !used[e]; e = next[e]) {
      used[e] = true;
      polygon[n++] = e;
    }
    int best_apex = 0, best_weight = -1;
    for (int apex = 0; apex < n; ++apex) {
      int thinnest = 1 << 30;
      for (int k = 1; k + 1 < n; ++k) {
        const int a = polygon[apex], b = polygon[(apex + k) % n], c = polygon[(apex + k + 1) % n];
        const int w = on_one_face(a, b, c) ? 0 : fan_triangle_weight(a, b, c);
        thinnest = w < thinnest ? w : thinnest;
      }
      if (thinnest > best_weight) {
        best_weight = thinnest;
        best_apex = apex;
      }
    }
    for (int k = 1; k + 1 < n; ++k) {
      row[out++] = static_cast<int8_t>(polygon[best_apex]);
      row[out++] = static_cast<int8_t>(polygon[(best_apex + k) % n]);
      row[out++] = static_cast<int8_t>(polygon[(best_apex + k + 1) % n]);
    }
  }
  return row;
}

constexpr std::array<std::array<int8_t, 16>, 256> make_tri_table() {
  std::array<std::array<int8_t, 16>, 256> table{};
  for (int c = 0; c < 256; ++c) table[c] = make_tri_row(c);
  return table;
}

constexpr auto kEdgeTable = make_edge_table();
constexpr auto kTriTable = make_tri_table();
static_assert(kEdgeTable[1] == 0x109 && kEdgeTable[2] == 0x203 && kEdgeTable[255] == 0);

}  // namespace

const std::array<uint16_t, 256> edgeTable = kEdgeTable;
const std::array<std::array<int8_t, 16>, 256> triTable = kTriTable;

}  // namespace vox::mesh
