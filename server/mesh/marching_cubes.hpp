// Marching cubes over one padded chunk block. One entry point, caller-owned scratch,
// caller-reused output: once the buffers are big enough nothing is allocated.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "server/mesh/chunk_mesh.hpp"
#include "server/mesh/edge_vertex.hpp"
#include "server/mesh/padded_block.hpp"

namespace vox::mesh {

inline constexpr int kRowsPerAxis = world::kChunkSize + 1;
inline constexpr int kRows = kRowsPerAxis * kRowsPerAxis;

// Per (y, z) row of samples: bit x set when sample (x, y, z) is solid; per axis, the cut
// edges starting at each sample and the index of the row's first vertex on that axis.
struct MeshScratch {
  std::array<uint64_t, kRows> solid;
  std::array<std::array<uint64_t, kRows>, 3> cut;
  std::array<std::array<uint32_t, kRows>, 3> first_vertex;
};

// Meshes cells [0, in.cells) of the block into `out` (cleared first). A vertex's fraction
// along its edge is rounded to 1/kFractionSteps; triangles of zero area at those positions
// are dropped. Vertices on the block's faces depend only on the samples of that face, so
// neighbouring chunks produce bit-identical vertices there (in world space). Afterwards
// scratch.solid holds the samples' solid bits (rows 0..cells), which the mesh codec transmits.
// `skip` (bit x of entry row_of(y, z)), when given, names cells whose triangles are left
// out: the seam cells of a level-of-detail chunk, meshed apart (lod_mesher.hpp). Their
// vertices stay.
using CellRows = std::array<uint64_t, kRows>;
void mesh_chunk(const PaddedBlock& in, MeshScratch& scratch, ChunkMesh& out,
                const CellRows* skip = nullptr);

// mesh_chunk in two halves, for meshing one block's cells several times with different
// `skip` sets (the seams variants of a level-of-detail chunk): mesh_vertices fills
// scratch and out's vertices (out.indices left empty) and returns whether some vertex sits
// on a sample (then zero-area triangles are looked for); mesh_triangles writes the
// triangles of those vertices into `indices`, as mesh_chunk would.
bool mesh_vertices(const PaddedBlock& in, MeshScratch& scratch, ChunkMesh& out);
void mesh_triangles(const MeshScratch& scratch, const std::array<int, 3>& cells,
                    std::span<const Vec3f> positions, bool on_corner, const CellRows* skip,
                    Buffer<uint32_t>& indices);

// For the same: the triangles of every cell (mesh_triangles without skip) and, per row
// (row_of(y, z)), where its triangles begin, where those of its cells after the first
// begin, where those of its last cell (x = cells[0] - 1) begin, and where they end. Then
// select_triangles writes what mesh_triangles with `skip` would, by copying: each row of
// `skip` must be empty, whole, or hold the first and/or the last cell only (the seam
// cells of a level-of-detail chunk, seam_cell_rows; asserted).
struct RowTriangles {
  std::array<uint32_t, kRows> begin, after_first, last, end;
};
void mesh_triangles_by_row(const MeshScratch& scratch, const std::array<int, 3>& cells,
                           std::span<const Vec3f> positions, bool on_corner,
                           Buffer<uint32_t>& indices, RowTriangles& rows);
void select_triangles(std::span<const uint32_t> all, const RowTriangles& rows,
                      const std::array<int, 3>& cells, const CellRows& skip,
                      Buffer<uint32_t>& indices);

// The topology half of the mesher, shared with the mesh codec's decoder, which rebuilds a
// mesh from the solid bits. Both read scratch.solid for rows y <= cells[1], z <= cells[2]
// (bits x <= cells[0]).
//
// Fills scratch.cut and scratch.first_vertex; returns the vertex count. Vertices are
// numbered row by row (row = y + 33 z), in each row x-edges, then y-edges, then z-edges,
// each by increasing x.
uint32_t index_cut_edges(MeshScratch& scratch, const std::array<int, 3>& cells);
// Upper bound of the triangle count (5 per cell whose corners differ).
size_t max_triangles(const MeshScratch& scratch, const std::array<int, 3>& cells);
// The number of triangles the tables give for these solid rows (before any zero-area
// triangle is dropped).
size_t table_triangles(const MeshScratch& scratch, const std::array<int, 3>& cells,
                       const CellRows* skip = nullptr);
// Writes the triangles of every cell whose corners differ, cells in (z, y, x) order, each
// cell's triangles in triTable order, as vertex index triples into `out` (room for
// max_triangles). keep(a, b, c) decides whether a triangle is written; cells named in
// `skip` are left out. Returns the number of triangles written. on_cell(x, y, z, written),
// when given, is called before each cell whose corners differ, with the triangles
// written so far.
struct NoCellHook {
  void operator()(int, int, int, size_t) const {}
};
template <class Keep, class OnCell = NoCellHook>
size_t emit_triangles(const MeshScratch& scratch, const std::array<int, 3>& cells, uint32_t* out,
                      Keep&& keep, const CellRows* skip = nullptr, OnCell&& on_cell = {});

}  // namespace vox::mesh

#include "server/mesh/marching_cubes_emit.inl"
