#include "server/mesh/lod_mesher.hpp"

#include <bit>
#include <cmath>

#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::mesh {
namespace {

using world::Density;
using world::kChunkSize;

constexpr int kHalfSteps = 2 * kFractionSteps;  // position step: 1/2048 of a cell
constexpr int kSeamStride[3] = {1, kSeamSide, kSeamSide* kSeamSide};
// kCubeFaces[f] lies on the chunk face (LodFace bit) when the cell is at that end.
constexpr int kCellFaceAxis[6] = {2, 2, 1, 1, 0, 0};
constexpr int kCellFaceSide[6] = {0, 1, 0, 1, 0, 1};

// The seam points of a cell's corners, of each Bourke edge's midpoint, and of the centre
// of each face kCellFaceAxis/kCellFaceSide names.
constexpr uint32_t kCornerPoints = [] {
  uint32_t m = 0;
  for (const auto& c : kCubeCorner) m |= 1u << seam_point(2 * c[0], 2 * c[1], 2 * c[2]);
  return m;
}();
constexpr std::array<int, 12> kEdgeMidpoint = [] {
  std::array<int, 12> m{};
  for (int e = 0; e < 12; ++e) {
    const auto& a = kCubeCorner[kEdgeCorners[e][0]];
    const auto& b = kCubeCorner[kEdgeCorners[e][1]];
    m[e] = seam_point(a[0] + b[0], a[1] + b[1], a[2] + b[2]);
  }
  return m;
}();
constexpr std::array<int, 6> kFaceCentre = [] {
  std::array<int, 6> m{};
  for (int f = 0; f < 6; ++f) {
    int q[3] = {1, 1, 1};
    q[kCellFaceAxis[f]] = 2 * kCellFaceSide[f];
    m[f] = seam_point(q[0], q[1], q[2]);
  }
  return m;
}();

// The marching-cubes vertex of the whole edge from coarse sample p along `axis`.
uint32_t whole_edge_vertex(const MeshScratch& s, const std::array<int, 3>& p, int axis) {
  const int r = detail::row_of(p[1], p[2]);
  return s.first_vertex[axis][r] +
         static_cast<uint32_t>(std::popcount(s.cut[axis][r] & detail::low_bits(p[0])));
}

std::array<int64_t, 3> scaled(const Vec3f& v) {
  return {static_cast<int64_t>(v.x * kHalfSteps), static_cast<int64_t>(v.y * kHalfSteps),
          static_cast<int64_t>(v.z * kHalfSteps)};
}

std::array<int64_t, 3> cross(const std::array<int64_t, 3>& a, const std::array<int64_t, 3>& b,
                             const std::array<int64_t, 3>& c) {
  const int64_t ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const int64_t wx = c[0] - a[0], wy = c[1] - a[1], wz = c[2] - a[2];
  return {uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx};
}

int64_t squared(const std::array<int64_t, 3>& n) { return n[0] * n[0] + n[1] * n[1] + n[2] * n[2]; }

class SeamMesher {
 public:
  SeamMesher(const LodBlock& in, LodScratch& s, ChunkMesh& out) : in_(in), s_(s), out_(out) {
    // A cell's splits depend only on where it lies on each axis: at the low end, inside or
    // at the high end of the chunk (27 places), so they are worked out once per place.
    constexpr int kEnds[3] = {0, 1, kChunkSize - 1};
    for (int z = 0; z < 3; ++z)
      for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 3; ++x) {
          const int place = x + 3 * y + 9 * z;
          splits_[place] = seam_cell_splits(in.seams, kEnds[x], kEnds[y], kEnds[z]);
          points_[place] = place_points(needed_points(splits_[place]));
        }
  }

  void mesh_cell(int x, int y, int z) {
    const int place = place_of(x) + 3 * place_of(y) + 9 * place_of(z);
    const SeamCellSplits splits = splits_[place];
    const PlacePoints& points = points_[place];
    // Every seam cell reads its points, most of them to find no surface: the hot loop.
    const Density* coarse = in_.coarse.density.get() + PaddedBlock::index(x, y, z);
    const Density* fine = in_.seam_density.get() + LodBlock::seam_index(2 * x, 2 * y, 2 * z);
    uint32_t solid = 0;
    for (int i = 0; i < 8; ++i)
      solid |= static_cast<uint32_t>(coarse[points.corner_offset[i]] > floor_)
               << points.corner_bit[i];
    for (int i = 0; i < points.fine_count; ++i)
      solid |= static_cast<uint32_t>(fine[points.fine_offset[i]] > floor_) << points.fine_bit[i];
    if (solid == 0 || solid == points.needed) return;
    SeamCellContour contour;
    contour_seam_cell(splits, solid, contour);
    int begin = 0;
    for (int k = 0; k < contour.polygons; ++k) {
      const int end = contour.polygon_end[k];
      uint32_t polygon[SeamCellContour::kMaxEdges];
      uint8_t faces[SeamCellContour::kMaxEdges];
      for (int i = begin; i < end; ++i) {
        polygon[i - begin] = vertex_of({x, y, z}, contour.edges[i]);
        faces[i - begin] = faces_of(contour.edges[i]);
      }
      fan(polygon, faces, end - begin);
      begin = end;
    }
  }

 private:
  static int place_of(int v) { return v == 0 ? 0 : v == kChunkSize - 1 ? 2 : 1; }

  // A place's seam points, as offsets from the cell's lowest corner: the 8 corners in the
  // coarse block, the others (each with an odd half-cell coordinate) in the seam grid.
  struct PlacePoints {
    uint32_t needed = 0;
    int fine_count = 0;
    std::array<int, 8> corner_offset{};
    std::array<uint8_t, 8> corner_bit{};
    std::array<int, 19> fine_offset{};
    std::array<uint8_t, 19> fine_bit{};
  };

  static PlacePoints place_points(uint32_t needed) {
    PlacePoints out;
    out.needed = needed;
    int corners = 0;
    for (uint32_t bits = needed; bits != 0; bits &= bits - 1) {
      const int p = std::countr_zero(bits);
      const auto q = seam_point_xyz(p);
      if (((q[0] | q[1] | q[2]) & 1) == 0) {
        out.corner_offset[corners] =
            PaddedBlock::index(q[0] / 2, q[1] / 2, q[2] / 2) - PaddedBlock::index(0, 0, 0);
        out.corner_bit[corners++] = static_cast<uint8_t>(p);
      } else {
        out.fine_offset[out.fine_count] =
            LodBlock::seam_index(q[0], q[1], q[2]) - LodBlock::seam_index(0, 0, 0);
        out.fine_bit[out.fine_count++] = static_cast<uint8_t>(p);
      }
    }
    return out;
  }

  // The seam points a cell reads: its corners, the midpoints of its split edges and the
  // centres of its faces with centres.
  static uint32_t needed_points(SeamCellSplits splits) {
    uint32_t needed = kCornerPoints;
    for (uint32_t e = splits.edges; e != 0; e &= e - 1)
      needed |= 1u << kEdgeMidpoint[std::countr_zero(e)];
    for (uint32_t f = splits.faces; f != 0; f &= f - 1)
      needed |= 1u << kFaceCentre[std::countr_zero(f)];
    return needed;
  }

  uint32_t vertex_of(const std::array<int, 3>& cell, SeamCellEdge e) {
    const auto a = seam_point_xyz(e.from), b = seam_point_xyz(e.to);
    std::array<int, 3> h{};
    int axis = 0;
    for (int i = 0; i < 3; ++i) {
      h[i] = 2 * cell[i] + a[i];
      if (b[i] != a[i]) axis = i;
    }
    if (b[axis] - a[axis] == 2)
      return whole_edge_vertex(s_.mc, {h[0] / 2, h[1] / 2, h[2] / 2}, axis);
    return half_edge_vertex(h, axis);
  }

  uint32_t half_edge_vertex(const std::array<int, 3>& h, int axis) {
    const uint32_t key = 1 + static_cast<uint32_t>((h[0] + 1) | ((h[1] + 1) << 7) |
                                                   ((h[2] + 1) << 14) | (axis << 21));
    uint32_t* slot = find(key);
    if (*slot == key) return s_.vertex_index[static_cast<size_t>(slot - s_.vertex_keys.data())];
    *slot = key;
    const uint32_t index = static_cast<uint32_t>(out_.positions.size());
    s_.vertex_index[static_cast<size_t>(slot - s_.vertex_keys.data())] = index;
    ++s_.vertex_entries;
    add_half_edge_vertex(h, axis);
    if (2 * s_.vertex_entries > s_.vertex_keys.size()) grow();
    return index;
  }

  uint32_t* find(uint32_t key) {
    // The product's high bits: its low ones depend on the key's low bits only (x and part
    // of y), which would crowd a face's vertices into a few runs.
    const size_t mask = s_.vertex_keys.size() - 1;
    const int shift = 32 - std::countr_zero(s_.vertex_keys.size());
    for (size_t i = (key * 0x9E3779B1u) >> shift;; i = (i + 1) & mask) {
      if (s_.vertex_keys[i] == key || s_.vertex_keys[i] == 0) return &s_.vertex_keys[i];
    }
  }

  void grow() {
    Buffer<uint32_t> keys(std::move(s_.vertex_keys)), index(std::move(s_.vertex_index));
    s_.vertex_keys.assign(keys.size() * 2, 0);
    s_.vertex_index.resize(keys.size() * 2);
    for (size_t i = 0; i < keys.size(); ++i) {
      if (keys[i] == 0) continue;
      uint32_t* slot = find(keys[i]);
      *slot = keys[i];
      s_.vertex_index[static_cast<size_t>(slot - s_.vertex_keys.data())] = index[i];
    }
  }

  // As marching_cubes.cpp makes a vertex, on the finer level's edge.
  void add_half_edge_vertex(const std::array<int, 3>& h, int axis) {
    const EdgeVertex v =
        edge_vertex(in_.seam_density.get(), in_.seam_material.get(),
                    LodBlock::seam_index(h[0], h[1], h[2]), axis, kSeamStride, floor_);
    Vec3f p{static_cast<float>(h[0]) * 0.5f, static_cast<float>(h[1]) * 0.5f,
            static_cast<float>(h[2]) * 0.5f};
    (&p.x)[axis] += static_cast<float>(v.fraction) * (1.0f / kHalfSteps);
    out_.positions.push_back(p);
    s_.seam_vertices.push_back({static_cast<uint8_t>(h[0]), static_cast<uint8_t>(h[1]),
                                static_cast<uint8_t>(h[2]), static_cast<uint8_t>(axis)});
    out_.normals.push_back(v.normal);
    out_.materials.push_back(v.material);
  }

  // Bit 2 * axis + side: the edge lies in that face plane of the cell.
  static uint8_t faces_of(SeamCellEdge e) {
    const auto a = seam_point_xyz(e.from), b = seam_point_xyz(e.to);
    uint8_t mask = 0;
    for (int axis = 0; axis < 3; ++axis) {
      if (a[axis] == b[axis] && a[axis] != 1)
        mask |= static_cast<uint8_t>(1u << (2 * axis + a[axis] / 2));
    }
    return mask;
  }

  // A triangle fan from the apex whose thinnest triangle is the widest, as the
  // marching-cubes table is made: triangles flat in a face of the cell count as thinnest
  // (the cell across may have the same one).
  void fan(const uint32_t* polygon, const uint8_t* faces, int n) {
    std::array<int64_t, 3> p[SeamCellContour::kMaxEdges];
    for (int i = 0; i < n; ++i) p[i] = scaled(out_.positions[polygon[i]]);
    int best_apex = 0;
    int64_t best = -1;
    for (int apex = 0; apex < n; ++apex) {
      int64_t thinnest = INT64_MAX;
      for (int k = 1; k + 1 < n; ++k) {
        const int b = (apex + k) % n, c = (apex + k + 1) % n;
        const bool flat = (faces[apex] & faces[b] & faces[c]) != 0;
        thinnest = std::min(thinnest, flat ? 0 : squared(cross(p[apex], p[b], p[c])));
      }
      if (thinnest > best) {
        best = thinnest;
        best_apex = apex;
      }
    }
    for (int k = 1; k + 1 < n; ++k) {
      const int b = (best_apex + k) % n, c = (best_apex + k + 1) % n;
      // Two vertices in one place: nothing to draw or to join. Three distinct ones on a
      // line stay: rounding put them there, and the triangle still joins its neighbours.
      if (p[best_apex] == p[b] || p[b] == p[c] || p[c] == p[best_apex]) continue;
      out_.indices.push_back(polygon[best_apex]);
      out_.indices.push_back(polygon[b]);
      out_.indices.push_back(polygon[c]);
    }
  }

  const LodBlock& in_;
  const world::Density floor_ = in_.coarse.solid_floor();  // the regular cells' rule too
  LodScratch& s_;
  ChunkMesh& out_;
  std::array<SeamCellSplits, 27> splits_;  // by place (mesh_cell)
  std::array<PlacePoints, 27> points_;
};

}  // namespace

SeamCellSplits seam_cell_splits(world::LodSeams seams, int x, int y, int z) {
  SeamCellSplits s;
  const int cell[3] = {x, y, z};
  for (int e = 0; e < 12; ++e) {
    const detail::EdgeSlot slot = detail::kEdgeSlot[e];
    const int p[3] = {x + slot.dx, y + slot.dy, z + slot.dz};
    const int a = slot.axis, b = (a + 1) % 3, c = (a + 2) % 3;
    bool split = false;
    for (const int o : {b, c}) {
      if (p[o] == 0) split |= ((seams.faces >> (2 * o)) & 1) != 0;
      if (p[o] == kChunkSize) split |= ((seams.faces >> (2 * o + 1)) & 1) != 0;
    }
    const bool b_end = p[b] == 0 || p[b] == kChunkSize, c_end = p[c] == 0 || p[c] == kChunkSize;
    if (b_end && c_end)
      split |=
          ((seams.edges >> world::lod_edge(a, p[b] == kChunkSize, p[c] == kChunkSize)) & 1) != 0;
    if (split) s.edges |= static_cast<uint16_t>(1u << e);
  }
  for (int f = 0; f < 6; ++f) {
    const int axis = kCellFaceAxis[f], side = kCellFaceSide[f];
    if (cell[axis] != (side == 0 ? 0 : kChunkSize - 1)) continue;
    if ((seams.faces >> (2 * axis + side)) & 1) s.faces |= static_cast<uint8_t>(1u << f);
  }
  return s;
}

void seam_cell_rows(world::LodSeams seams, CellRows& out) {
  // A cell has an edge on a split face's plane when it is in that face's layer, and one on
  // a split chunk edge when it is in the column along it: whole rows or end bits.
  out.fill(0);
  if (seams.empty()) return;
  constexpr int kLast = kChunkSize - 1;
  const uint64_t all = detail::low_bits(kChunkSize), x_lo = 1, x_hi = uint64_t{1} << kLast;
  auto face = [&](int f) { return ((seams.faces >> f) & 1) != 0; };
  auto edge = [&](int axis, int a, int b) {
    return ((seams.edges >> world::lod_edge(axis, a, b)) & 1) != 0;
  };
  for (int z = 0; z < kChunkSize; ++z) {
    for (int y = 0; y < kChunkSize; ++y) {
      const int ys = y == 0 ? 0 : y == kLast ? 1 : -1, zs = z == 0 ? 0 : z == kLast ? 1 : -1;
      uint64_t row = (face(0) ? x_lo : 0) | (face(1) ? x_hi : 0);
      if ((ys >= 0 && face(2 + ys)) || (zs >= 0 && face(4 + zs))) row = all;
      if (ys >= 0 && zs >= 0 && edge(0, ys, zs)) row = all;  // along x: sides of y, z
      if (zs >= 0) row |= (edge(1, zs, 0) ? x_lo : 0) | (edge(1, zs, 1) ? x_hi : 0);  // z, x
      if (ys >= 0) row |= (edge(2, 0, ys) ? x_lo : 0) | (edge(2, 1, ys) ? x_hi : 0);  // x, y
      out[detail::row_of(y, z)] = row;
    }
  }
}

void mesh_lod_vertices(const LodBlock& in, LodScratch& s) {
  s.on_corner = mesh_vertices(in.coarse, s.mc, s.regular);
  mesh_triangles_by_row(s.mc, in.coarse.cells, s.regular.positions, s.on_corner, s.regular.indices,
                        s.regular_rows);
}

void mesh_lod_chunk(const LodBlock& in, LodScratch& s, ChunkMesh& out) {
  mesh_lod_vertices(in, s);
  mesh_lod_variant(in, s, out);
}

void mesh_lod_variant(const LodBlock& in, LodScratch& s, ChunkMesh& out) {
  s.seams = in.seams;
  seam_cell_rows(in.seams, s.seam_cells);
  out.positions.assign(s.regular.positions.begin(), s.regular.positions.end());
  out.normals.assign(s.regular.normals.begin(), s.regular.normals.end());
  out.materials.assign(s.regular.materials.begin(), s.regular.materials.end());
  // The regular triangles: those of the block's cells but the seam cells (whole face
  // layers, or the end cells of rows along an edge).
  select_triangles(s.regular.indices, s.regular_rows, in.coarse.cells, s.seam_cells, out.indices);
  s.regular_vertices = static_cast<uint32_t>(out.vertex_count());
  s.regular_triangles = static_cast<uint32_t>(out.triangle_count());
  s.seam_vertices.clear();
  if (in.seams.empty()) return;

  if (s.vertex_keys.empty()) {
    s.vertex_keys.assign(4096, 0);
    s.vertex_index.resize(4096);
  } else {
    std::fill(s.vertex_keys.begin(), s.vertex_keys.end(), 0u);
  }
  s.vertex_entries = 0;
  SeamMesher seam(in, s, out);
  for (int z = 0; z < kChunkSize; ++z)
    for (int y = 0; y < kChunkSize; ++y)
      for (uint64_t bits = s.seam_cells[detail::row_of(y, z)]; bits != 0; bits &= bits - 1)
        seam.mesh_cell(std::countr_zero(bits), y, z);
}

}  // namespace vox::mesh
