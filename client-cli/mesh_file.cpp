#include "client-cli/mesh_file.hpp"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string_view>

namespace vox::cli {
namespace {

std::string extension_of(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// Output gathered in a 1 MiB block and written a block at a time: fprintf and fwrite per
// value cost more than the meshing.
class BlockWriter {
 public:
  explicit BlockWriter(std::FILE* f) : f_(f), buffer_(new char[kSize]) {}
  ~BlockWriter() { flush(); }
  BlockWriter(const BlockWriter&) = delete;
  BlockWriter& operator=(const BlockWriter&) = delete;

  // Room for n <= kMaxRecord bytes; the caller fills exactly `n`.
  char* room(size_t n) {
    assert(n <= kMaxRecord);
    if (used_ + n > kSize) flush();
    char* p = buffer_.get() + used_;
    used_ += n;
    return p;
  }
  // Takes back what room() gave and was not filled.
  void unused(size_t n) { used_ -= n; }
  template <class T>
  void put(const T& v) {
    static_assert(std::endian::native == std::endian::little,
                  "binary writers assume a little-endian host");
    std::memcpy(room(sizeof v), &v, sizeof v);
  }
  void bytes(const void* p, size_t n) {
    flush();
    std::fwrite(p, 1, n, f_);
  }
  void text(std::string_view t) {
    if (t.size() > kMaxRecord) return bytes(t.data(), t.size());
    std::memcpy(room(t.size()), t.data(), t.size());
  }
  void flush() {
    if (used_ > 0) std::fwrite(buffer_.get(), 1, used_, f_);
    used_ = 0;
  }

  static constexpr size_t kMaxRecord = 256;

 private:
  static constexpr size_t kSize = size_t{1} << 20;
  std::FILE* f_;
  std::unique_ptr<char[]> buffer_;
  size_t used_ = 0;
};

// printf's %.6g (or %.5f for normals) written with to_chars.
char* put_general(char* p, float v) {
  return std::to_chars(p, p + 32, v, std::chars_format::general, 6).ptr;
}
char* put_fixed5(char* p, float v) {
  return std::to_chars(p, p + 32, v, std::chars_format::fixed, 5).ptr;
}
char* put_uint(char* p, uint32_t v) { return std::to_chars(p, p + 16, v).ptr; }

// "PREFIX x y z\n" with each coordinate through `put`.
template <class Put>
void put_vec3_line(BlockWriter& w, std::string_view prefix, const mesh::Vec3f& v, Put put) {
  char* const start = w.room(BlockWriter::kMaxRecord);
  char* p = start;
  std::memcpy(p, prefix.data(), prefix.size());
  p += prefix.size();
  p = put(p, v.x);
  *p++ = ' ';
  p = put(p, v.y);
  *p++ = ' ';
  p = put(p, v.z);
  *p++ = '\n';
  w.unused(BlockWriter::kMaxRecord - static_cast<size_t>(p - start));
}

void write_obj(std::FILE* f, const mesh::ChunkMesh& m) {
  BlockWriter w(f);
  w.text("# voxeld mesh: " + std::to_string(m.vertex_count()) + " vertices, " +
         std::to_string(m.triangle_count()) + " triangles\n");
  for (const auto& p : m.positions) put_vec3_line(w, "v ", p, put_general);
  for (const auto& n : m.normals) put_vec3_line(w, "vn ", n, put_fixed5);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    char* const start = w.room(BlockWriter::kMaxRecord);
    char* p = start;
    *p++ = 'f';
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = m.indices[t + k] + 1;
      *p++ = ' ';
      p = put_uint(p, i);
      *p++ = '/';
      *p++ = '/';
      p = put_uint(p, i);
    }
    *p++ = '\n';
    w.unused(BlockWriter::kMaxRecord - static_cast<size_t>(p - start));
  }
}

void write_ply(std::FILE* f, const mesh::ChunkMesh& m) {
  BlockWriter w(f);
  w.text("ply\nformat binary_little_endian 1.0\ncomment voxeld mesh\nelement vertex " +
         std::to_string(m.vertex_count()) +
         "\nproperty float x\nproperty float y\nproperty float z\n"
         "property float nx\nproperty float ny\nproperty float nz\nproperty uchar material\n"
         "element face " +
         std::to_string(m.triangle_count()) +
         "\nproperty list uchar uint vertex_indices\nend_header\n");
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    char* p = w.room(25);
    std::memcpy(p, &m.positions[v], 12);
    std::memcpy(p + 12, &m.normals[v], 12);
    p[24] = static_cast<char>(m.materials[v]);
  }
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    char* p = w.room(13);
    p[0] = 3;
    std::memcpy(p + 1, &m.indices[t], 12);
  }
}

// Binary glTF 2.0: one mesh, one primitive (POSITION, NORMAL, COLOR_0, uint32 indices).
// The mesh's own arrays are written as they are, without a copy of the whole buffer.
void write_glb(std::FILE* f, const mesh::ChunkMesh& m) {
  if (m.empty())
    throw MeshFileError("no triangles to write: glTF accessors need at least one element");
  const size_t v = m.vertex_count(), i = m.indices.size();
  const size_t bin_size = v * 36 + i * 4;  // a multiple of 4
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
      bin_size, v * 12, v * 12, v * 12, v * 24, v * 12, v * 36, i * 4, v, lo[0], lo[1], lo[2],
      hi[0], hi[1], hi[2], v, v, i);
  std::string js(json);
  while (js.size() % 4 != 0) js.push_back(' ');
  const uint32_t total =
      12 + 8 + static_cast<uint32_t>(js.size()) + 8 + static_cast<uint32_t>(bin_size);
  BlockWriter w(f);
  for (uint32_t word : {0x46546C67u, 2u, total, static_cast<uint32_t>(js.size()), 0x4E4F534Au})
    w.put(word);
  w.text(js);
  for (uint32_t word : {static_cast<uint32_t>(bin_size), 0x004E4942u}) w.put(word);
  w.bytes(m.positions.data(), v * 12);
  w.bytes(m.normals.data(), v * 12);
  for (size_t k = 0; k < v; ++k)
    std::memcpy(w.room(12), material_colour(m.materials[k]).data(), 12);
  w.bytes(m.indices.data(), i * 4);
}

void write_seed_text(std::FILE* f, const mesh::ChunkMesh& m) {
  BlockWriter w(f);
  w.text(std::to_string(m.vertex_count()) + "\n");
  for (const auto& p : m.positions) put_vec3_line(w, "", p, put_general);
  w.text(std::to_string(m.triangle_count()) + "\n");
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    char* const start = w.room(BlockWriter::kMaxRecord);
    char* p = start;
    for (int k = 0; k < 3; ++k) {
      p = put_uint(p, m.indices[t + k]);
      *p++ = k < 2 ? ' ' : '\n';
    }
    w.unused(BlockWriter::kMaxRecord - static_cast<size_t>(p - start));
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
  // The file it replaces goes first: renaming over an existing file makes ext4 write the
  // new one out before rename returns (its auto_da_alloc), which tripled the time to
  // write a mesh. A killed run leaves the old file or the new one, whole, never a part of
  // one (killed between the two calls: neither). Like VTK's writers, nothing forces the
  // data to disk: after a power loss the new file may be empty.
  std::error_code ec;
  if (std::filesystem::is_regular_file(std::filesystem::symlink_status(path, ec)))
    std::filesystem::remove(path, ec);
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw MeshFileError(path + ": cannot rename into place: " + ec.message());
  }
}

}  // namespace vox::cli
