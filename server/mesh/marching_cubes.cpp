// Marching cubes (W. Lorensen, H. Cline, SIGGRAPH 1987) with the 256-case tables of
// P. Bourke / C. Bloyd (marching_cubes_tables.hpp), organised after the edge-based passes
// of Flying Edges (W. Schroeder et al., 2015):
//   1. classify: one bit per sample, 33 bits per x-row;
//   2. cut edges per row and axis from xor-ed rows; a vertex's index is the row's first
//      index plus the number of cut edges before it in the row (popcount), so vertices
//      are shared inside the chunk without any per-cell cache;
//   3. vertices: interpolate each cut edge once, normal from central differences;
//   4. triangles: only cells whose 8 corners differ, found with row bit masks.
#include "server/mesh/marching_cubes.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>

#include "server/mesh/marching_cubes_tables.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vox::mesh {
namespace {

using world::Density;
constexpr int kStride[3] = {1, kBlockSide, kBlockSide* kBlockSide};

// Bit x of the result is set when sample x of the row (x in 0..32) is solid: its density
// above `floor` (0, or -1 when a density of 0 is solid).
inline uint64_t classify_row(const Density* row, Density floor) {
#if defined(__SSE2__)
  const __m128i f = _mm_set1_epi16(floor);
  uint64_t bits = 0;
  for (int i = 0; i < 32; i += 16) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + i));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + i + 8));
    const __m128i packed = _mm_packs_epi16(_mm_cmpgt_epi16(a, f), _mm_cmpgt_epi16(b, f));
    bits |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(packed))) << i;
  }
  return bits | (static_cast<uint64_t>(row[32] > floor) << 32);
#else
  uint64_t bits = 0;
  for (int x = 0; x <= 32; ++x) bits |= static_cast<uint64_t>(row[x] > floor) << x;
  return bits;
#endif
}

// Exact for a triangle of one cell: its coordinates are multiples of 1/kFractionSteps at
// most one voxel apart, so the scaled differences are integers of at most kFractionSteps
// (products under 2^21). Zero area needs a vertex on a sample: two vertices meet only
// there, and three on one line lie on a cell edge's line, two of them at its ends.
inline bool has_zero_area(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  auto scaled = [](float v, float from) {
    return static_cast<int32_t>((v - from) * kFractionSteps);
  };
  const int32_t ux = scaled(b.x, a.x), uy = scaled(b.y, a.y), uz = scaled(b.z, a.z);
  const int32_t wx = scaled(c.x, a.x), wy = scaled(c.y, a.y), wz = scaled(c.z, a.z);
  return uy * wz == uz * wy && uz * wx == ux * wz && ux * wy == uy * wx;
}

}  // namespace

void mesh_chunk(const PaddedBlock& in, MeshScratch& s, ChunkMesh& out, const CellRows* skip) {
  const bool on_corner = mesh_vertices(in, s, out);
  mesh_triangles(s, in.cells, out.positions, on_corner, skip, out.indices);
}

bool mesh_vertices(const PaddedBlock& in, MeshScratch& s, ChunkMesh& out) {
  const int ny = in.cells[1], nz = in.cells[2];
  const Density* dens = in.density.get();
  const world::Material* mats = in.material.get();
  const Density floor = in.solid_floor();

  // --- 1. classify samples [0, n] on each axis ---------------------------------------
  for (int z = 0; z <= nz; ++z)
    for (int y = 0; y <= ny; ++y)
      s.solid[detail::row_of(y, z)] = classify_row(dens + PaddedBlock::index(0, y, z), floor);

  // --- 2. cut edges per row and axis; first vertex index of each (row, axis) ---------
  const uint32_t vertex_count = index_cut_edges(s, in.cells);

  // --- 3. one vertex per cut edge -----------------------------------------------------
  out.positions.resize(vertex_count);
  out.normals.resize(vertex_count);
  out.materials.resize(vertex_count);
  Vec3f* pos = out.positions.data();
  Vec3f* nrm = out.normals.data();
  uint8_t* mat = out.materials.data();
  bool on_corner =
      false;  // some vertex sits on a sample (fraction 0 or 1): check for flat triangles
  for (int z = 0; z <= nz; ++z) {
    for (int y = 0; y <= ny; ++y) {
      const int r = detail::row_of(y, z);
      for (int a = 0; a < 3; ++a) {
        for (uint64_t bits = s.cut[a][r]; bits != 0; bits &= bits - 1) {
          const int x = std::countr_zero(bits);
          const EdgeVertex v =
              edge_vertex(dens, mats, PaddedBlock::index(x, y, z), a, kStride, floor);
          const float tq = edge_offset(v.fraction);
          on_corner |= (v.fraction == 0) | (v.fraction == kFractionSteps);
          // Selects instead of indexing a member by axis, which would force p through memory.
          *pos++ = {static_cast<float>(x) + (a == 0 ? tq : 0.0f),
                    static_cast<float>(y) + (a == 1 ? tq : 0.0f),
                    static_cast<float>(z) + (a == 2 ? tq : 0.0f)};
          *nrm++ = v.normal;
          *mat++ = v.material;
        }
      }
    }
  }

  out.indices.clear();
  return on_corner;
}

// --- 4. triangles of the cells whose corners differ -------------------------------------
namespace {

// The tables' triangles of the cells not skipped into `indices`, but those of zero area
// at the rounded positions.
template <class OnCell>
size_t write_triangles(const MeshScratch& s, const std::array<int, 3>& cells,
                       std::span<const Vec3f> positions, bool on_corner, const CellRows* skip,
                       Buffer<uint32_t>& indices, OnCell&& on_cell) {
  indices.resize(max_triangles(s, cells) * 3);
  const Vec3f* vpos = positions.data();
  const size_t triangles = emit_triangles(
      s, cells, indices.data(),
      [&](uint32_t a, uint32_t b, uint32_t c) {
        return !on_corner || !has_zero_area(vpos[a], vpos[b], vpos[c]);
      },
      skip, on_cell);
  indices.resize(triangles * 3);
  return triangles;
}

}  // namespace

void mesh_triangles(const MeshScratch& s, const std::array<int, 3>& cells,
                    std::span<const Vec3f> positions, bool on_corner, const CellRows* skip,
                    Buffer<uint32_t>& indices) {
  write_triangles(s, cells, positions, on_corner, skip, indices, NoCellHook{});
}

void mesh_triangles_by_row(const MeshScratch& s, const std::array<int, 3>& cells,
                           std::span<const Vec3f> positions, bool on_corner,
                           Buffer<uint32_t>& indices, RowTriangles& rows) {
  constexpr uint32_t kUnset = UINT32_MAX;
  rows.begin.fill(kUnset);
  rows.after_first.fill(kUnset);
  rows.last.fill(kUnset);
  const auto written = static_cast<uint32_t>(write_triangles(
      s, cells, positions, on_corner, nullptr, indices, [&](int x, int y, int z, size_t so_far) {
        const int r = detail::row_of(y, z);
        const auto at = static_cast<uint32_t>(so_far);
        if (rows.begin[r] == kUnset) rows.begin[r] = at;
        if (x > 0 && rows.after_first[r] == kUnset) rows.after_first[r] = at;
        if (x == cells[0] - 1) rows.last[r] = at;
      }));
  // Rows (in the order written) that had no cell, or no cell after the first or no last
  // cell: those parts are empty, ending where the next part begins.
  uint32_t end = written;
  for (int z = cells[2] - 1; z >= 0; --z) {
    for (int y = cells[1] - 1; y >= 0; --y) {
      const int r = detail::row_of(y, z);
      rows.end[r] = end;
      if (rows.last[r] == kUnset) rows.last[r] = end;
      if (rows.after_first[r] == kUnset) rows.after_first[r] = rows.last[r];
      if (rows.begin[r] == kUnset) rows.begin[r] = rows.after_first[r];
      end = rows.begin[r];
    }
  }
}

void select_triangles(std::span<const uint32_t> all, const RowTriangles& rows,
                      const std::array<int, 3>& cells, const CellRows& skip,
                      Buffer<uint32_t>& indices) {
  const uint64_t whole = detail::low_bits(cells[0]), first = 1,
                 last = uint64_t{1} << (cells[0] - 1);
  indices.resize(all.size());
  uint32_t* out = indices.data();
  const auto copy = [&](uint32_t from, uint32_t to) {
    std::copy(all.begin() + 3 * size_t{from}, all.begin() + 3 * size_t{to}, out);
    out += 3 * size_t{to - from};
  };
  for (int z = 0; z < cells[2]; ++z) {
    for (int y = 0; y < cells[1]; ++y) {
      const int r = detail::row_of(y, z);
      const uint64_t k = skip[r] & whole;
      if (k == 0) {
        copy(rows.begin[r], rows.end[r]);
      } else if (k != whole) {
        assert((k & ~(first | last)) == 0 && "a row skips an inner cell");
        if ((k & first) == 0) copy(rows.begin[r], rows.after_first[r]);
        copy(rows.after_first[r], rows.last[r]);
        if ((k & last) == 0) copy(rows.last[r], rows.end[r]);
      }
    }
  }
  indices.resize(static_cast<size_t>(out - indices.data()));
}

uint32_t index_cut_edges(MeshScratch& s, const std::array<int, 3>& cells) {
  const int nx = cells[0], ny = cells[1], nz = cells[2];
  const uint64_t x_edges = detail::low_bits(nx), yz_edges = detail::low_bits(nx + 1);
  uint32_t vertex_count = 0;
  for (int z = 0; z <= nz; ++z) {
    for (int y = 0; y <= ny; ++y) {
      const int r = detail::row_of(y, z);
      const uint64_t row = s.solid[r];
      s.cut[0][r] = (row ^ (row >> 1)) & x_edges;
      s.cut[1][r] = y < ny ? (row ^ s.solid[detail::row_of(y + 1, z)]) & yz_edges : 0;
      s.cut[2][r] = z < nz ? (row ^ s.solid[detail::row_of(y, z + 1)]) & yz_edges : 0;
      for (int a = 0; a < 3; ++a) {
        s.first_vertex[a][r] = vertex_count;
        vertex_count += static_cast<uint32_t>(std::popcount(s.cut[a][r]));
      }
    }
  }
  return vertex_count;
}

size_t table_triangles(const MeshScratch& s, const std::array<int, 3>& cells,
                       const CellRows* skip) {
  static const auto kCount = [] {
    std::array<uint8_t, 256> count{};
    for (int c = 0; c < 256; ++c)
      while (count[c] < 5 && triTable[c][3 * count[c]] >= 0) ++count[c];
    return count;
  }();
  size_t total = 0;
  for (int z = 0; z < cells[2]; ++z) {
    for (int y = 0; y < cells[1]; ++y) {
      const uint64_t r00 = s.solid[detail::row_of(y, z)], r10 = s.solid[detail::row_of(y + 1, z)],
                     r01 = s.solid[detail::row_of(y, z + 1)],
                     r11 = s.solid[detail::row_of(y + 1, z + 1)];
      uint64_t mixed = detail::mixed_cells(s, cells[0], y, z);
      if (skip != nullptr) mixed &= ~(*skip)[detail::row_of(y, z)];
      for (uint64_t left = mixed; left != 0; left &= left - 1) {
        total += kCount[detail::cube_index(r00, r10, r01, r11, std::countr_zero(left))];
      }
    }
  }
  return total;
}

size_t max_triangles(const MeshScratch& s, const std::array<int, 3>& cells) {
  size_t mixed = 0;
  for (int z = 0; z < cells[2]; ++z)
    for (int y = 0; y < cells[1]; ++y)
      mixed += std::popcount(detail::mixed_cells(s, cells[0], y, z));
  return mixed * 5;
}

}  // namespace vox::mesh
