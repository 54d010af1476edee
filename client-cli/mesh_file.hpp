// Writing meshes: Wavefront OBJ (positions, normals), binary little-endian PLY (positions,
// normals, a material per vertex), binary glTF 2.0 (.glb: positions, normals, a colour
// per material) and the seed 002 text format (vertex count, positions, triangle count,
// index triples), chosen by the file extension. The file appears whole
// or not at all: it is written beside the target and renamed into place.
#pragma once

#include <array>
#include <stdexcept>
#include <string>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::cli {

enum class MeshFormat { kObj, kPly, kGlb, kSeedText };

struct MeshFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// .obj, .ply, .glb, .txt; throws MeshFileError for anything else.
MeshFormat mesh_format_for(const std::string& path);
void write_mesh(const std::string& path, const mesh::ChunkMesh& mesh);
// The colour (linear RGB, 0..1) a material is drawn with in .glb files.
std::array<float, 3> material_colour(uint8_t material);

}  // namespace vox::cli
