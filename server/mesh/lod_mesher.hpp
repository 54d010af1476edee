// Meshes a level-of-detail chunk with its seams: marching cubes over the
// chunk's own level for every cell, except the cells touching a split face or edge
// (lod_seams.hpp), which are contoured from the finer level's samples there too
// (seam_cell.hpp). Where a finer chunk meets this one, both meshes then have the same
// vertices and segments on the shared face: the combined surface is closed.
//
// Positions are chunk-local in the level's cells (0..32; world = lo + 2^k * local).
// Vertices of whole edges are the marching-cubes vertices, numbered as in
// marching_cubes.hpp (a vertex on a split edge stays, unused); vertices on half edges come
// after them, on 1/2048 of a cell (1/1024 of a finer cell, so they equal the finer
// chunk's). Outside the seam cells, triangles of zero area at the rounded positions are
// dropped (as marching_cubes.hpp does); in them, only triangles with two vertices in one
// place: three on a line still join their neighbours, and dropping them opened the
// surface where a sample lay within rounding of the level.
#pragma once

#include <cstdint>

#include "server/mesh/chunk_mesh.hpp"
#include "server/mesh/lod_block.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/seam_cell.hpp"

namespace vox::mesh {

// The half-cell edge a seam vertex lies on: its lower end in half-cell units of the chunk
// (0..64) and its axis.
struct HalfEdge {
  uint8_t x = 0, y = 0, z = 0, axis = 0;
  friend constexpr bool operator==(const HalfEdge&, const HalfEdge&) = default;
};

// A worker's buffers; once warm, meshing allocates nothing. After mesh_lod_chunk: the
// mesh's first regular_vertices vertices and regular_triangles triangles are the
// marching-cubes ones; seam_vertices[i] is the edge of vertex regular_vertices + i.
struct LodScratch {
  // The regular vertices of the block last given to mesh_lod_vertices, with its topology
  // in mc, shared by every seams variant meshed from that block.
  ChunkMesh regular;  // every cell's triangles, by row in regular_rows
  RowTriangles regular_rows;
  bool on_corner = false;  // some regular vertex sits on a sample
  world::LodSeams seams;   // of the variant last meshed (normalized)
  uint32_t regular_vertices = 0;
  uint32_t regular_triangles = 0;
  Buffer<HalfEdge> seam_vertices;
  MeshScratch mc;
  CellRows seam_cells{};  // bit x of row_of(y, z): cell (x, y, z) touches a split edge
  // The half-edge vertices made so far: open addressing, key + 1 (0 = empty) -> index.
  Buffer<uint32_t> vertex_keys;
  Buffer<uint32_t> vertex_index;
  size_t vertex_entries = 0;
};

// Which edges of cell (x, y, z) are split and which of its faces carry centres.
SeamCellSplits seam_cell_splits(world::LodSeams seams, int x, int y, int z);

// The seam cells of a chunk with these (normalized) seams: bit x of row_of(y, z) set when
// cell (x, y, z) touches a split edge.
void seam_cell_rows(world::LodSeams seams, CellRows& out);

// The calling thread only (one scratch per thread). A chunk's seams variants share its
// regular vertices and triangles (they differ in which cells are seam cells):
// mesh_lod_vertices makes them once from the block, with every cell's triangles; then
// mesh_lod_variant copies them but the seam cells' and meshes the seam cells of the
// variant in.seams (any subset of the seams the block was gathered for), from the same
// block, as often as needed. mesh_lod_chunk does both.
void mesh_lod_vertices(const LodBlock& in, LodScratch& scratch);
void mesh_lod_variant(const LodBlock& in, LodScratch& scratch, ChunkMesh& out);
void mesh_lod_chunk(const LodBlock& in, LodScratch& scratch, ChunkMesh& out);

}  // namespace vox::mesh
