// Writing meshes: Wavefront OBJ (positions, normals), binary little-endian PLY (positions,
// normals, a material per vertex) and the seed 002 text format (vertex count, positions,
// triangle count, index triples), chosen by the file extension. The file appears whole
// or not at all: it is written beside the target and renamed into place.
#pragma once

#include <stdexcept>
#include <string>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::cli {

enum class MeshFormat { kObj, kPly, kSeedText };

struct MeshFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// .obj, .ply, .txt; throws MeshFileError for anything else.
MeshFormat mesh_format_for(const std::string& path);
void write_mesh(const std::string& path, const mesh::ChunkMesh& mesh);

}  // namespace vox::cli
