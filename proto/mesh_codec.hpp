// The chunk mesh encoding (docs/PROTOCOL.md, "Mesh encoding"): pure functions, no I/O.
//
// A chunk mesh from the marching-cubes mesher is fixed by the samples' solid bits (which
// give the cut edges, the vertex order and, through the published tables, the triangles)
// plus, per vertex, the fraction along its edge, a normal and a material. The encoding
// sends exactly that: solid-bit rows xor-ed with the previous row (only the rows where
// that is not zero), then per-vertex byte planes. Indices are not sent, so inserting vertices never
// rewrites later indices, and a local edit changes a local run of bytes in each section (good for
// zstd deltas).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "proto/result.hpp"
#include "server/mesh/chunk_mesh.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::proto {

using Bytes = std::vector<uint8_t>;

inline constexpr uint8_t kMeshFormat = 1;
inline constexpr uint8_t kLodMeshFormat = 2;  // a level-of-detail chunk with its seams
inline constexpr int kFractionSteps = mesh::kFractionSteps;  // edge fraction step: 1/1024 voxel
inline constexpr uint32_t kMeshTableRevision = mesh::kMeshTableRevision;  // Welcome

struct DecodeLimits {
  size_t max_encoding_bytes = size_t{4} << 20;  // an encoding (decompressed) over this is refused
};

// Scratch reused across calls: once warm, encode and decode allocate only the output.
struct CodecScratch {
  mesh::MeshScratch topology;
  mesh::CellRows seam_cells;
  std::array<uint64_t, mesh::kRows> row_diff;
  std::vector<uint32_t> triangles;
  // The encoder's rows and vertex planes of the level-of-detail vertex pass last encoded
  // (a LodScratch and the caller's key for its pass): the same in each seams variant.
  std::vector<uint8_t> shared;
  const mesh::LodScratch* shared_of = nullptr;
  uint64_t shared_pass = 0;
};

// `topology` is the mesher's scratch right after mesh_chunk() produced `mesh` (its solid
// rows, cut edges and vertex numbering for `cells`). Writes the encoding into `out`,
// replacing what it held (its capacity is reused).
void encode_mesh(const mesh::ChunkMesh& mesh, const mesh::MeshScratch& topology,
                 const std::array<int, 3>& cells, CodecScratch& scratch, Bytes& out);

// Format 2 (docs/PROTOCOL.md §2.7): a level-of-detail chunk from mesh_lod_chunk, whose
// scratch (`lod`) still holds the seams, topology, regular counts and seam vertices.
// `vertex_pass`: the seams variants of one mesh_lod_vertices pass share their rows and
// vertex planes; a caller encoding several of them through `scratch` gives each the same
// nonzero key, and each new pass a new one (a count it keeps beside the scratches), and
// those bytes are written once and copied. 0: written every time.
void encode_lod_mesh(const mesh::ChunkMesh& mesh, const mesh::LodScratch& lod,
                     CodecScratch& scratch, Bytes& out, uint64_t vertex_pass = 0);

// Rebuilds the mesh (format 1 or 2) into `out` (its buffers reused); never trusts the bytes: any
// inconsistency is an error (and `out` holds no meaningful mesh).
std::optional<Error> decode_mesh(std::span<const uint8_t> encoding, const DecodeLimits& limits,
                                 CodecScratch& scratch, mesh::ChunkMesh& out);
// The same, returning a new mesh.
Result<mesh::ChunkMesh> decode_mesh(std::span<const uint8_t> encoding, const DecodeLimits& limits,
                                    CodecScratch& scratch);
Result<mesh::ChunkMesh> decode_mesh(std::span<const uint8_t> encoding,
                                    const DecodeLimits& limits = {});

// Octahedral normal in two bytes (docs/PROTOCOL.md): encode and decode.
std::array<uint8_t, 2> encode_normal(const mesh::Vec3f& n);
mesh::Vec3f decode_normal(uint8_t u, uint8_t v);

}  // namespace vox::proto
