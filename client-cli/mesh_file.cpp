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
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

void write_obj(std::FILE* f, const mesh::ChunkMesh& m) {
  std::fprintf(f, "# voxeld mesh: %zu vertices, %zu triangles\n", m.vertex_count(),
               m.triangle_count());
  for (const auto& p : m.positions) std::fprintf(f, "v %.6g %.6g %.6g\n", p.x, p.y, p.z);
  for (const auto& n : m.normals) std::fprintf(f, "vn %.5f %.5f %.5f\n", n.x, n.y, n.z);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const uint32_t a = m.indices[t] + 1, b = m.indices[t + 1] + 1, c = m.indices[t + 2] + 1;
    std::fprintf(f, "f %u//%u %u//%u %u//%u\n", a, a, b, b, c, c);
  }
}

template <class T>
void put(std::FILE* f, T v) {
  static_assert(std::endian::native == std::endian::little,
                "PLY writer assumes a little-endian host");
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

// Binary glTF 2.0: one mesh, one primitive (POSITION, NORMAL, COLOR_0, uint32 indices).
void write_glb(std::FILE* f, const mesh::ChunkMesh& m) {
  if (m.empty())
    throw MeshFileError("no triangles to write: glTF accessors need at least one element");
  const size_t v = m.vertex_count(), i = m.indices.size();
  std::vector<uint8_t> bin;
  auto append = [&bin](const void* p, size_t n) {
    bin.insert(bin.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
  };
  append(m.positions.data(), v * 12);
  append(m.normals.data(), v * 12);
  for (size_t k = 0; k < v; ++k) append(material_colour(m.materials[k]).data(), 12);
  append(m.indices.data(), i * 4);
  float lo[3] = {m.positions[0].x, m.positions[0].y, m.positions[0].z},
        hi[3] = {lo[0], lo[1], lo[2]};
  for (const auto& p : m.positions) {
    const float c[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c[a]);
      hi[a] = std::max(hi[a], c[a]);
    }
  }
  char json[2048];
  std::snprintf(
      json, sizeof json,
      "{\"asset\":{\"version\":\"2.0\",\"generator\":\"voxeld voxel-cli\"},\"scene\":0,"
      "\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":1,\"COLOR_0\":2},"
      "\"indices\":3,\"mode\":4}]}],"
      "\"buffers\":[{\"byteLength\":%zu}],"
      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%zu,\"target\":34962},"
      "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},"
      "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},"
      "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34963}],"
      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\","
      "\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]},"
      "{\"bufferView\":1,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\"},"
      "{\"bufferView\":2,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\"},"
      "{\"bufferView\":3,\"componentType\":5125,\"count\":%zu,\"type\":\"SCALAR\"}]}",
      bin.size(), v * 12, v * 12, v * 12, v * 24, v * 12, v * 36, i * 4, v, lo[0], lo[1], lo[2],
      hi[0], hi[1], hi[2], v, v, i);
  std::string js(json);
  while (js.size() % 4 != 0) js.push_back(' ');
  while (bin.size() % 4 != 0) bin.push_back(0);
  const uint32_t total =
      12 + 8 + static_cast<uint32_t>(js.size()) + 8 + static_cast<uint32_t>(bin.size());
  for (uint32_t word : {0x46546C67u, 2u, total, static_cast<uint32_t>(js.size()), 0x4E4F534Au})
    put(f, word);
  std::fwrite(js.data(), 1, js.size(), f);
  for (uint32_t word : {static_cast<uint32_t>(bin.size()), 0x004E4942u}) put(f, word);
  std::fwrite(bin.data(), 1, bin.size(), f);
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
  if (ext == ".glb") return MeshFormat::kGlb;
  if (ext == ".txt") return MeshFormat::kSeedText;
  throw MeshFileError(path + ": unknown output format '" + ext +
                      "' (use .obj, .ply, .glb or .txt)");
}

std::array<float, 3> material_colour(uint8_t material) {
  switch (material) {
    case 1:
      return {0.28f, 0.55f, 0.18f};  // grass
    case 2:
      return {0.45f, 0.31f, 0.18f};  // dirt
    case 3:
      return {0.50f, 0.50f, 0.52f};  // stone
    case 4:
      return {0.86f, 0.79f, 0.55f};  // sand
    default: {                       // any other material: a stable colour from its id
      const uint32_t h = material * 2654435761u;
      return {0.3f + 0.6f * static_cast<float>(h & 0xFF) / 255.0f,
              0.3f + 0.6f * static_cast<float>((h >> 8) & 0xFF) / 255.0f,
              0.3f + 0.6f * static_cast<float>((h >> 16) & 0xFF) / 255.0f};
    }
  }
}

void write_mesh(const std::string& path, const mesh::ChunkMesh& mesh) {
  const MeshFormat format = mesh_format_for(path);
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) throw MeshFileError(path + ": cannot create: " + std::strerror(errno));
  std::setvbuf(f, nullptr, _IOFBF, 1 << 20);
  switch (format) {
    case MeshFormat::kObj:
      write_obj(f, mesh);
      break;
    case MeshFormat::kPly:
      write_ply(f, mesh);
      break;
    case MeshFormat::kGlb:
      try {
        write_glb(f, mesh);
      } catch (...) {
        std::fclose(f);
        std::remove(tmp.c_str());
        throw;
      }
      break;
    case MeshFormat::kSeedText:
      write_seed_text(f, mesh);
      break;
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
