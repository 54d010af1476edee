// Inline part of marching_cubes.hpp: the triangle pass, a template so that the mesher's
// and the codec's "keep" tests inline into the hot loop.
#pragma once

#include <bit>

#include "server/mesh/edge_vertex.hpp"
#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::mesh {
namespace detail {

constexpr int row_of(int y, int z) { return y + kRowsPerAxis * z; }
constexpr uint64_t low_bits(int n) { return n >= 64 ? ~0ull : (1ull << n) - 1; }

using mesh::EdgeSlot;
using mesh::kEdgeSlot;

// Bit x set when cell (x, y, z) has corners on both sides of the surface.
inline uint64_t mixed_cells(const MeshScratch& s, int nx, int y, int z) {
  const uint64_t r00 = s.solid[row_of(y, z)], r10 = s.solid[row_of(y + 1, z)],
                 r01 = s.solid[row_of(y, z + 1)], r11 = s.solid[row_of(y + 1, z + 1)];
  const uint64_t all = r00 & r10 & r01 & r11, any = r00 | r10 | r01 | r11;
  return ~(all & (all >> 1)) & (any | (any >> 1)) & low_bits(nx);
}

// Bourke cube index of cell x from the four sample rows around it.
inline unsigned cube_index(uint64_t r00, uint64_t r10, uint64_t r01, uint64_t r11, int x) {
  // Bourke corner order: (0,0,0) (1,0,0) (1,1,0) (0,1,0), then the same at z + 1.
  return static_cast<unsigned>(((r00 >> x) & 3) | (((r10 >> (x + 1)) & 1) << 2) |
                               (((r10 >> x) & 1) << 3) | (((r01 >> x) & 3) << 4) |
                               (((r11 >> (x + 1)) & 1) << 6) | (((r11 >> x) & 1) << 7));
}

}  // namespace detail

template <class Keep, class OnCell>
size_t emit_triangles(const MeshScratch& s, const std::array<int, 3>& cells, uint32_t* out,
                      Keep&& keep, const CellRows* skip, OnCell&& on_cell) {
  uint32_t* idx = out;
  for (int z = 0; z < cells[2]; ++z) {
    for (int y = 0; y < cells[1]; ++y) {
      uint64_t cells_left = detail::mixed_cells(s, cells[0], y, z);
      if (skip != nullptr) cells_left &= ~(*skip)[detail::row_of(y, z)];
      if (cells_left == 0) continue;
      const uint64_t r00 = s.solid[detail::row_of(y, z)], r10 = s.solid[detail::row_of(y + 1, z)],
                     r01 = s.solid[detail::row_of(y, z + 1)],
                     r11 = s.solid[detail::row_of(y + 1, z + 1)];
      // Per edge of this row of cells: the cut mask and first vertex of the row it lies in.
      uint64_t edge_cut[12];
      uint32_t edge_first[12];
      for (int e = 0; e < 12; ++e) {
        const detail::EdgeSlot slot = detail::kEdgeSlot[e];
        const int r = detail::row_of(y + slot.dy, z + slot.dz);
        edge_cut[e] = s.cut[slot.axis][r];
        edge_first[e] = s.first_vertex[slot.axis][r];
      }
      for (; cells_left != 0; cells_left &= cells_left - 1) {
        const int x = std::countr_zero(cells_left);
        on_cell(x, y, z, static_cast<size_t>(idx - out) / 3);
        const unsigned cube_index = detail::cube_index(r00, r10, r01, r11, x);
        // Cut edges before this cell's lower corner (dx = 0) or upper corner (dx = 1).
        const uint64_t before[2] = {detail::low_bits(x), detail::low_bits(x + 1)};
        uint32_t vertex[12];
        for (unsigned edges = edgeTable[cube_index]; edges != 0; edges &= edges - 1) {
          const int e = std::countr_zero(edges);
          vertex[e] =
              edge_first[e] +
              static_cast<uint32_t>(std::popcount(edge_cut[e] & before[detail::kEdgeSlot[e].dx]));
        }
        for (const int8_t* tri = triTable[cube_index].data(); *tri >= 0; tri += 3) {
          const uint32_t a = vertex[tri[0]], b = vertex[tri[1]], c = vertex[tri[2]];
          if (!keep(a, b, c)) continue;
          idx[0] = a;
          idx[1] = b;
          idx[2] = c;
          idx += 3;
        }
      }
    }
  }
  return static_cast<size_t>(idx - out) / 3;
}

}  // namespace vox::mesh
