#include "client-cli/mesh_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace vox::cli {
namespace {

std::string extension_of(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

void write_obj(std::FILE* f, const mesh::ChunkMesh& m) {
  std::fprintf(f, "# voxeld mesh: %zu vertices, %zu triangles\n", m.vertex_count(), m.triangle_count());
  for (const auto& p : m.positions) std::fprintf(f, "v %.6g %.6g %.6g\n", p.x, p.y, p.z);
  for (const auto& n : m.normals) std::fprintf(f, "vn %.5f %.5f %.5f\n", n.x, n.y, n.z);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const uint32_t a = m.indices[t] + 1, b = m.indices[t + 1] + 1, c = m.indices[t + 2] + 1;
    std::fprintf(f, "f %u//%u %u//%u %u//%u\n", a, a, b, b, c, c);
  }
}

template <class T>
void put(std::FILE* f, T v) {
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes a little-endian host");
  std::fwrite(&v, sizeof v, 1, f);
}

void write_ply(std::FILE* f, const mesh::ChunkMesh& m) {
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\ncomment voxeld mesh\n"
               "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
               "property float nx\nproperty float ny\nproperty float nz\nproperty uchar material\n"
               "element face %zu\nproperty list uchar uint vertex_indices\nend_header\n",
               m.vertex_count(), m.triangle_count());
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const auto& p = m.positions[v];
    const auto& n = m.normals[v];
    for (float c : {p.x, p.y, p.z, n.x, n.y, n.z}) put(f, c);
    put(f, m.materials[v]);
  }
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    put(f, uint8_t{3});
    for (int k = 0; k < 3; ++k) put(f, m.indices[t + k]);
  }
}

void write_seed_text(std::FILE* f, const mesh::ChunkMesh& m) {
  std::fprintf(f, "%zu\n", m.vertex_count());
  for (const auto& p : m.positions) std::fprintf(f, "%.6g %.6g %.6g\n", p.x, p.y, p.z);
  std::fprintf(f, "%zu\n", m.triangle_count());
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    std::fprintf(f, "%u %u %u\n", m.indices[t], m.indices[t + 1], m.indices[t + 2]);
  }
}

}  // namespace

MeshFormat mesh_format_for(const std::string& path) {
  const std::string ext = extension_of(path);
  if (ext == ".obj") return MeshFormat::kObj;
  if (ext == ".ply") return MeshFormat::kPly;
  if (ext == ".txt") return MeshFormat::kSeedText;
  throw MeshFileError(path + ": unknown output format '" + ext + "' (use .obj, .ply or .txt)");
}

void write_mesh(const std::string& path, const mesh::ChunkMesh& mesh) {
  const MeshFormat format = mesh_format_for(path);
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) throw MeshFileError(path + ": cannot create: " + std::strerror(errno));
  std::setvbuf(f, nullptr, _IOFBF, 1 << 20);
  switch (format) {
    case MeshFormat::kObj: write_obj(f, mesh); break;
    case MeshFormat::kPly: write_ply(f, mesh); break;
    case MeshFormat::kSeedText: write_seed_text(f, mesh); break;
  }
  const bool failed = std::ferror(f) != 0;
  if (std::fclose(f) != 0 || failed) {
    std::remove(tmp.c_str());
    throw MeshFileError(path + ": write failed: " + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw MeshFileError(path + ": cannot rename into place: " + ec.message());
  }
}

}  // namespace vox::cli
