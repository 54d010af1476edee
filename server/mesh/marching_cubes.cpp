// Marching cubes (W. Lorensen, H. Cline, SIGGRAPH 1987) with the 256-case tables of
// P. Bourke / C. Bloyd (marching_cubes_tables.hpp), organised after the edge-based passes
// of Flying Edges (W. Schroeder et al., 2015):
//   1. classify: one bit per sample, 33 bits per x-row;
//   2. cut edges per row and axis from xor-ed rows; a vertex's index is the row's first
//      index plus the number of cut edges before it in the row (popcount), so vertices
//      are shared inside the chunk without any per-cell cache;
//   3. vertices: interpolate each cut edge once, normal from central differences;
//   4. triangles: only cells whose 8 corners differ, found with row bit masks.
#include "mesh/marching_cubes.hpp"

#include <bit>
#include <cmath>

#include "mesh/marching_cubes_tables.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vox::mesh {
namespace {

using world::Density;
constexpr int kStride[3] = {1, kBlockSide, kBlockSide * kBlockSide};

// Bourke edge -> (axis, offset of its lower sample in the cell).
struct EdgeSlot {
  int8_t axis, dx, dy, dz;
};
constexpr EdgeSlot kEdgeSlot[12] = {
    {0, 0, 0, 0}, {1, 1, 0, 0}, {0, 0, 1, 0}, {1, 0, 0, 0}, {0, 0, 0, 1}, {1, 1, 0, 1},
    {0, 0, 1, 1}, {1, 0, 0, 1}, {2, 0, 0, 0}, {2, 1, 0, 0}, {2, 1, 1, 0}, {2, 0, 1, 0},
};

constexpr int row_of(int y, int z) { return y + kRowsPerAxis * z; }
constexpr uint64_t low_bits(int n) { return n >= 64 ? ~0ull : (1ull << n) - 1; }

// Bit x of the result is set when sample x of the row (x in 0..32) is solid.
inline uint64_t classify_row(const Density* row) {
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  uint64_t bits = 0;
  for (int i = 0; i < 32; i += 16) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + i));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + i + 8));
    const __m128i packed = _mm_packs_epi16(_mm_cmpgt_epi16(a, zero), _mm_cmpgt_epi16(b, zero));
    bits |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(packed))) << i;
  }
  return bits | (static_cast<uint64_t>(row[32] > 0) << 32);
#else
  uint64_t bits = 0;
  for (int x = 0; x <= 32; ++x) bits |= static_cast<uint64_t>(row[x] > 0) << x;
  return bits;
#endif
}

inline Vec3f gradient(const Density* d, int i) {
  return {static_cast<float>(d[i + kStride[0]] - d[i - kStride[0]]),
          static_cast<float>(d[i + kStride[1]] - d[i - kStride[1]]),
          static_cast<float>(d[i + kStride[2]] - d[i - kStride[2]])};
}

}  // namespace

void mesh_chunk(const PaddedBlock& in, MeshScratch& s, ChunkMesh& out) {
  const int nx = in.cells[0], ny = in.cells[1], nz = in.cells[2];
  const Density* dens = in.density.get();
  const world::Material* mats = in.material.get();

  // --- 1. classify samples [0, n] on each axis ---------------------------------------
  for (int z = 0; z <= nz; ++z)
    for (int y = 0; y <= ny; ++y) s.solid[row_of(y, z)] = classify_row(dens + PaddedBlock::index(0, y, z));

  // --- 2. cut edges per row and axis; first vertex index of each (row, axis) ---------
  const uint64_t x_edges = low_bits(nx), yz_edges = low_bits(nx + 1);
  uint32_t vertex_count = 0;
  for (int z = 0; z <= nz; ++z) {
    for (int y = 0; y <= ny; ++y) {
      const int r = row_of(y, z);
      const uint64_t row = s.solid[r];
      s.cut[0][r] = (row ^ (row >> 1)) & x_edges;
      s.cut[1][r] = y < ny ? (row ^ s.solid[row_of(y + 1, z)]) & yz_edges : 0;
      s.cut[2][r] = z < nz ? (row ^ s.solid[row_of(y, z + 1)]) & yz_edges : 0;
      for (int a = 0; a < 3; ++a) {
        s.first_vertex[a][r] = vertex_count;
        vertex_count += static_cast<uint32_t>(std::popcount(s.cut[a][r]));
      }
    }
  }

  // --- 3. one vertex per cut edge -----------------------------------------------------
  out.positions.resize(vertex_count);
  out.normals.resize(vertex_count);
  out.materials.resize(vertex_count);
  Vec3f* pos = out.positions.data();
  Vec3f* nrm = out.normals.data();
  uint8_t* mat = out.materials.data();
  bool on_corner = false;  // some vertex sits exactly on a sample: check for flat triangles
  for (int z = 0; z <= nz; ++z) {
    for (int y = 0; y <= ny; ++y) {
      const int r = row_of(y, z);
      for (int a = 0; a < 3; ++a) {
        for (uint64_t bits = s.cut[a][r]; bits != 0; bits &= bits - 1) {
          const int x = std::countr_zero(bits);
          const int i0 = PaddedBlock::index(x, y, z), i1 = i0 + kStride[a];
          const int d0 = dens[i0], d1 = dens[i1];
          on_corner |= (d0 == 0) | (d1 == 0);
          const float t = static_cast<float>(d0) / static_cast<float>(d0 - d1);
          Vec3f p{static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
          (&p.x)[a] += t;
          *pos++ = p;
          const Vec3f g0 = gradient(dens, i0), g1 = gradient(dens, i1);
          Vec3f n{-(g0.x + t * (g1.x - g0.x)), -(g0.y + t * (g1.y - g0.y)), -(g0.z + t * (g1.z - g0.z))};
          const float len2 = n.x * n.x + n.y * n.y + n.z * n.z;
          if (len2 > 0.0f) {
            const float inv = 1.0f / std::sqrt(len2);
            n = {n.x * inv, n.y * inv, n.z * inv};
          } else {  // flat field: point along the edge, from the solid end to the air end
            n = {};
            (&n.x)[a] = d0 > 0 ? 1.0f : -1.0f;
          }
          *nrm++ = n;
          *mat++ = d0 > 0 ? mats[i0] : mats[i1];
        }
      }
    }
  }

  // --- 4. triangles of the cells whose corners differ ---------------------------------
  size_t mixed_cells = 0;
  const uint64_t cell_bits = low_bits(nx);
  for (int z = 0; z < nz; ++z) {
    for (int y = 0; y < ny; ++y) {
      const uint64_t r00 = s.solid[row_of(y, z)], r10 = s.solid[row_of(y + 1, z)],
                     r01 = s.solid[row_of(y, z + 1)], r11 = s.solid[row_of(y + 1, z + 1)];
      const uint64_t all = r00 & r10 & r01 & r11, any = r00 | r10 | r01 | r11;
      mixed_cells += std::popcount(~(all & (all >> 1)) & (any | (any >> 1)) & cell_bits);
    }
  }
  out.indices.resize(mixed_cells * 15);
  uint32_t* idx = out.indices.data();
  const Vec3f* vpos = out.positions.data();
  for (int z = 0; z < nz; ++z) {
    for (int y = 0; y < ny; ++y) {
      const uint64_t r00 = s.solid[row_of(y, z)], r10 = s.solid[row_of(y + 1, z)],
                     r01 = s.solid[row_of(y, z + 1)], r11 = s.solid[row_of(y + 1, z + 1)];
      const uint64_t all = r00 & r10 & r01 & r11, any = r00 | r10 | r01 | r11;
      for (uint64_t cells = ~(all & (all >> 1)) & (any | (any >> 1)) & cell_bits; cells != 0;
           cells &= cells - 1) {
        const int x = std::countr_zero(cells);
        // Bourke corner order: (0,0,0) (1,0,0) (1,1,0) (0,1,0), then the same at z + 1.
        const unsigned cube_index =
            static_cast<unsigned>(((r00 >> x) & 3) | (((r10 >> (x + 1)) & 1) << 2) |
                                  (((r10 >> x) & 1) << 3) | (((r01 >> x) & 3) << 4) |
                                  (((r11 >> (x + 1)) & 1) << 6) | (((r11 >> x) & 1) << 7));
        uint32_t vertex[12];
        for (unsigned edges = edgeTable[cube_index]; edges != 0; edges &= edges - 1) {
          const int e = std::countr_zero(edges);
          const EdgeSlot slot = kEdgeSlot[e];
          const int r = row_of(y + slot.dy, z + slot.dz);
          vertex[e] = s.first_vertex[slot.axis][r] +
                      static_cast<uint32_t>(std::popcount(s.cut[slot.axis][r] & low_bits(x + slot.dx)));
        }
        const int8_t* tri = triTable[cube_index].data();
        for (; *tri >= 0; tri += 3) {
          const uint32_t a = vertex[tri[0]], b = vertex[tri[1]], c = vertex[tri[2]];
          if (on_corner && (vpos[a] == vpos[b] || vpos[b] == vpos[c] || vpos[a] == vpos[c])) continue;
          idx[0] = a;
          idx[1] = b;
          idx[2] = c;
          idx += 3;
        }
      }
    }
  }
  out.indices.resize(static_cast<size_t>(idx - out.indices.data()));
}

}  // namespace vox::mesh
