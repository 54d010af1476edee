// Where a level-k chunk of a level-of-detail layout meets finer chunks.
//
// Seams are made crack-free on the coarser side: on a face whose neighbour is one level
// finer, the coarse chunk's cells read the finer level's samples there too (every edge of
// the face split at its midpoint, every face cell given its centre sample), so its surface
// meets the finer chunk's along the same segments. Along a chunk edge, a finer chunk may
// touch only diagonally (across the edge, not a face): the cell edges on that line are
// split as well. Together the 6 face bits and 12 edge bits are a chunk's seams; a chunk
// with no finer neighbour has none and meshes like a level-0 chunk.
//
// Chunk edges are numbered axis * 4 + side bits: the edge runs along `axis`; of the two
// other axes (axis + 1, axis + 2, mod 3), bit 0 says it lies at the high end of the first
// (coordinate 32 rather than 0), bit 1 at the high end of the second.
#pragma once

#include <array>
#include <cstdint>

namespace vox::world {

struct LodSeams {
  uint8_t faces = 0;   // LodFace bits (lod_layout.hpp): across this face, finer chunks
  uint16_t edges = 0;  // chunk edges split by a finer chunk (including the faces' edges)
  friend constexpr bool operator==(const LodSeams&, const LodSeams&) = default;
  bool empty() const { return faces == 0 && edges == 0; }
};

inline constexpr int kChunkEdges = 12;

// The chunk edge along `axis` at the given ends (0 low, 1 high) of the two other axes.
constexpr int lod_edge(int axis, int side_a, int side_b) { return axis * 4 + side_a + 2 * side_b; }

// Offset (in chunks of the same level) of the chunk across edge e, diagonally.
constexpr std::array<int, 3> lod_edge_direction(int e) {
  std::array<int, 3> d{};
  const int axis = e / 4;
  d[(axis + 1) % 3] = (e & 1) != 0 ? 1 : -1;
  d[(axis + 2) % 3] = (e & 2) != 0 ? 1 : -1;
  return d;
}

// The chunk edges lying on face f (f = 2 * axis + side, the LodFace bit order).
constexpr uint16_t lod_face_edges(int f) {
  const int axis = f / 2, side = f % 2;
  uint16_t mask = 0;
  for (int e = 0; e < kChunkEdges; ++e) {
    const int a = e / 4;
    if (a == axis) continue;
    // The edge's side on `axis`: axis is a's first or second other axis.
    const int bit = (a + 1) % 3 == axis ? (e & 1) : (e >> 1) & 1;
    if (bit == side) mask = static_cast<uint16_t>(mask | (1u << e));
  }
  return mask;
}

// The seams with the edges of every split face added.
constexpr LodSeams normalized(LodSeams s) {
  for (int f = 0; f < 6; ++f)
    if ((s.faces >> f) & 1) s.edges = static_cast<uint16_t>(s.edges | lod_face_edges(f));
  return s;
}

}  // namespace vox::world
