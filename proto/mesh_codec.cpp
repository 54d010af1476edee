#include "proto/mesh_codec.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>

#include "proto/crc32c.hpp"

namespace vox::proto {
namespace {

using mesh::kRowsPerAxis;
using mesh::detail::row_of;
constexpr size_t kHeaderBytes = 16;
constexpr size_t kLodHeaderBytes = 27;  // format 2: seams, seam vertex and triangle counts
constexpr size_t kSeamVertexBytes =
    9;  // half point x, y, z, axis, fraction (2), normal (2), material
constexpr size_t kChecksumBytes = 4;
constexpr uint32_t kMaxVertices = 3 * kRowsPerAxis * kRowsPerAxis * kRowsPerAxis;
constexpr uint32_t kMaxTriangles = 5 * 32 * 32 * 32;
// Half edges on the 6 faces and 12 edges of a chunk; triangles of 6 * 32^2 seam cells.
constexpr uint32_t kMaxSeamVertices = 6 * 2 * 64 * 65 + 12 * 64;
constexpr uint32_t kMaxSeamTriangles = 6 * 32 * 32 * 48;

// What format 2 adds to format 1.
struct LodSection {
  world::LodSeams seams;
  const mesh::CellRows* seam_cells;
  const mesh::LodScratch* lod;  // encoder only
  uint64_t vertex_pass;         // encoder only: the caller's key of lod's vertex pass (0: none)
};

// The encoding's header (docs/PROTOCOL.md §2.4, §2.7), written by write_header and read
// by parse_header: one layout, in one place.
struct Header {
  bool lod = false;  // format 2, whose header also holds the seams and their counts
  std::array<int, 3> cells{};
  uint32_t vertices = 0, triangles = 0, dropped = 0;
  world::LodSeams seams;
  uint32_t seam_vertices = 0, seam_triangles = 0;
  size_t bytes() const { return lod ? kLodHeaderBytes : kHeaderBytes; }
};

size_t row_bytes(int cells_x) { return static_cast<size_t>(cells_x + 1 + 7) / 8; }

void put_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint32_t get_u32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
         static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
}

// p has room for h.bytes().
void write_header(const Header& h, uint8_t* p) {
  p[0] = h.lod ? kLodMeshFormat : kMeshFormat;
  for (int a = 0; a < 3; ++a) p[1 + a] = static_cast<uint8_t>(h.cells[a]);
  put_u32(p + 4, h.vertices);
  put_u32(p + 8, h.triangles);
  put_u32(p + 12, h.dropped);
  if (!h.lod) return;
  p[16] = h.seams.faces;
  p[17] = static_cast<uint8_t>(h.seams.edges);
  p[18] = static_cast<uint8_t>(h.seams.edges >> 8);
  put_u32(p + 19, h.seam_vertices);
  put_u32(p + 23, h.seam_triangles);
}

// The fields as written; `in` holds a known format and at least its header's bytes.
Header parse_header(std::span<const uint8_t> in) {
  Header h;
  h.lod = in[0] == kLodMeshFormat;
  h.cells = {in[1], in[2], in[3]};
  h.vertices = get_u32(in.data() + 4);
  h.triangles = get_u32(in.data() + 8);
  h.dropped = get_u32(in.data() + 12);
  if (h.lod) {
    h.seams = {in[16], static_cast<uint16_t>(in[17] | in[18] << 8)};
    h.seam_vertices = get_u32(in.data() + 19);
    h.seam_triangles = get_u32(in.data() + 23);
  }
  return h;
}

float sign_not_zero(float v) { return v >= 0.0f ? 1.0f : -1.0f; }

// Calls fn(vertex, axis, x, y, z) for every vertex in vertex order.
template <class Fn>
void for_each_vertex(const mesh::MeshScratch& t, const std::array<int, 3>& cells, Fn&& fn) {
  uint32_t v = 0;
  for (int z = 0; z <= cells[2]; ++z) {
    for (int y = 0; y <= cells[1]; ++y) {
      const int r = row_of(y, z);
      if ((t.cut[0][r] | t.cut[1][r] | t.cut[2][r]) == 0)
        continue;  // most rows: far from the surface
      for (int a = 0; a < 3; ++a)
        for (uint64_t bits = t.cut[a][r]; bits != 0; bits &= bits - 1)
          fn(v++, a, std::countr_zero(bits), y, z);
    }
  }
}

}  // namespace

std::array<uint8_t, 2> encode_normal(const mesh::Vec3f& n) {
  const float l1 = std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z);
  const float inv = l1 > 0 ? 1.0f / l1 : 0.0f;
  float px = n.x * inv, py = n.y * inv;
  if (n.z < 0.0f) {
    const float ox = (1.0f - std::fabs(py)) * sign_not_zero(px),
                oy = (1.0f - std::fabs(px)) * sign_not_zero(py);
    px = ox;
    py = oy;
  }
  // Round to nearest (the value is >= 0, so adding 0.5 and truncating rounds).
  auto q = [](float p) {
    return static_cast<uint8_t>(std::clamp(p * 0.5f + 0.5f, 0.0f, 1.0f) * 255.0f + 0.5f);
  };
  return {q(px), q(py)};
}

namespace {
inline mesh::Vec3f decode_normal_inline(uint8_t u, uint8_t v) {
  const float px = static_cast<float>(u) * (2.0f / 255.0f) - 1.0f,
              py = static_cast<float>(v) * (2.0f / 255.0f) - 1.0f;
  const float z = 1.0f - std::fabs(px) - std::fabs(py);
  // Lower hemisphere (z < 0): unfold. Written as selects so that it compiles branch-free.
  const float fx = (1.0f - std::fabs(py)) * std::copysign(1.0f, px),
              fy = (1.0f - std::fabs(px)) * std::copysign(1.0f, py);
  const float x = z < 0.0f ? fx : px, y = z < 0.0f ? fy : py;
  // Correctly rounded float32 operations in a fixed order (-ffp-contract=off, no
  // reciprocal estimate), so that every decoder following PROTOCOL §2.4 gets these bits.
  const float length = std::sqrt(x * x + y * y + z * z);
  return {x / length, y / length, z / length};
}
}  // namespace

mesh::Vec3f decode_normal(uint8_t u, uint8_t v) { return decode_normal_inline(u, v); }

namespace {

// Format 2's seam vertices (planes after the dropped list) and triangles, at p.
void write_seam_section(const mesh::ChunkMesh& m, const mesh::LodScratch& lod, uint8_t* p) {
  const auto count = static_cast<uint32_t>(lod.seam_vertices.size());
  uint8_t* plane[kSeamVertexBytes];
  for (size_t k = 0; k < kSeamVertexBytes; ++k) plane[k] = p + k * count;
  uint8_t prev_m = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const mesh::HalfEdge e = lod.seam_vertices[i];
    const uint32_t v = lod.regular_vertices + i;
    const mesh::Vec3f pos = m.positions[v];
    const uint8_t lower[3] = {e.x, e.y, e.z};
    const float frac = (&pos.x)[e.axis] * 2.0f - static_cast<float>(lower[e.axis]);
    const auto q = static_cast<uint16_t>(
        std::clamp(frac * kFractionSteps + 0.5f, 0.0f, float{kFractionSteps}));
    const auto n = encode_normal(m.normals[v]);
    const uint8_t bytes[kSeamVertexBytes] = {e.x,
                                             e.y,
                                             e.z,
                                             e.axis,
                                             static_cast<uint8_t>(q),
                                             static_cast<uint8_t>(q >> 8),
                                             n[0],
                                             n[1],
                                             static_cast<uint8_t>(m.materials[v] - prev_m)};
    for (size_t k = 0; k < kSeamVertexBytes; ++k) plane[k][i] = bytes[k];
    prev_m = m.materials[v];
  }
  p += kSeamVertexBytes * count;
  for (size_t k = 3 * size_t{lod.regular_triangles}; k < m.indices.size(); ++k, p += 4)
    put_u32(p, m.indices[k]);
}

// The ordinals, in table order, of the table triangles the mesher dropped (zero area),
// into scratch.triangles.
void collect_dropped(const mesh::ChunkMesh& m, const mesh::MeshScratch& t,
                     const std::array<int, 3>& cells, const mesh::CellRows* skip,
                     uint32_t triangles, CodecScratch& scratch) {
  std::vector<uint32_t>& dropped = scratch.triangles;
  dropped.clear();
  if (mesh::table_triangles(t, cells, skip) == triangles) return;
  size_t next = 0;
  uint32_t ordinal = 0;
  // Walks the table-derived triangles against the mesh's; writes nothing (keep is false).
  mesh::emit_triangles(
      t, cells, nullptr,
      [&](uint32_t a, uint32_t b, uint32_t c) {
        const bool kept = next < triangles && m.indices[3 * next] == a &&
                          m.indices[3 * next + 1] == b && m.indices[3 * next + 2] == c;
        if (kept)
          ++next;
        else
          dropped.push_back(ordinal);
        ++ordinal;
        return false;
      },
      skip);
}

// Solid rows xor-ed with the row before them (z-major, then y) into diff; returns how many
// are not zero (only those are sent, flagged in a bitmap).
size_t diff_rows(const mesh::MeshScratch& t, const std::array<int, 3>& cells,
                 std::array<uint64_t, mesh::kRows>& diff) {
  size_t nonzero = 0, r = 0;
  uint64_t previous = 0;
  for (int z = 0; z <= cells[2]; ++z) {
    for (int y = 0; y <= cells[1]; ++y, ++r) {
      const uint64_t row = t.solid[row_of(y, z)] & mesh::detail::low_bits(cells[0] + 1);
      diff[r] = row ^ previous;
      previous = row;
      nonzero += diff[r] != 0 ? 1 : 0;
    }
  }
  return nonzero;
}

// The bitmap (one bit per row, LSB first) and the non-zero differences, B bytes each.
uint8_t* write_rows(const std::array<uint64_t, mesh::kRows>& diff, size_t rows, size_t rb,
                    uint8_t* p) {
  std::memset(p, 0, (rows + 7) / 8);
  for (size_t r = 0; r < rows; ++r)
    p[r / 8] = static_cast<uint8_t>(p[r / 8] | (diff[r] != 0 ? 1u << (r % 8) : 0u));
  p += (rows + 7) / 8;
  for (size_t r = 0; r < rows; ++r) {
    if (diff[r] == 0) continue;
    for (size_t b = 0; b < rb; ++b) *p++ = static_cast<uint8_t>(diff[r] >> (8 * b));
  }
  return p;
}

// Per-vertex planes: fraction low bytes, fraction high bytes, normal u, normal v, and
// material as the difference from the previous vertex's (mod 256).
uint8_t* write_vertex_planes(const mesh::ChunkMesh& m, const mesh::MeshScratch& t,
                             const std::array<int, 3>& cells, uint32_t vertices, uint8_t* p) {
  uint8_t* frac_lo = p;
  uint8_t* frac_hi = frac_lo + vertices;
  uint8_t* nu = frac_hi + vertices;
  uint8_t* nv = nu + vertices;
  uint8_t* mat = nv + vertices;
  uint8_t prev_m = 0;
  for_each_vertex(t, cells, [&](uint32_t v, int a, int x, int y, int z) {
    const mesh::Vec3f pos = m.positions[v];
    const int lower[3] = {x, y, z};
    const float frac = (&pos.x)[a] - static_cast<float>(lower[a]);
    const auto q = static_cast<uint16_t>(
        std::clamp(frac * kFractionSteps + 0.5f, 0.0f, float{kFractionSteps}));
    frac_lo[v] = static_cast<uint8_t>(q);
    frac_hi[v] = static_cast<uint8_t>(q >> 8);
    const auto n = encode_normal(m.normals[v]);
    nu[v] = n[0];
    nv[v] = n[1];
    mat[v] = static_cast<uint8_t>(m.materials[v] - prev_m);
    prev_m = m.materials[v];
  });
  return mat + vertices;
}

void encode_impl(const mesh::ChunkMesh& m, const mesh::MeshScratch& t,
                 const std::array<int, 3>& cells, const LodSection* lod, CodecScratch& scratch,
                 Bytes& out) {
  const auto vertices =
      static_cast<uint32_t>(lod != nullptr ? lod->lod->regular_vertices : m.vertex_count());
  const auto triangles =
      static_cast<uint32_t>(lod != nullptr ? lod->lod->regular_triangles : m.triangle_count());
  collect_dropped(m, t, cells, lod != nullptr ? lod->seam_cells : nullptr, triangles, scratch);
  const auto dropped = static_cast<uint32_t>(scratch.triangles.size());
  const size_t rb = row_bytes(cells[0]);
  const size_t rows = static_cast<size_t>(cells[1] + 1) * static_cast<size_t>(cells[2] + 1);
  const size_t nonzero = diff_rows(t, cells, scratch.row_diff);

  const size_t seam_vertices = lod != nullptr ? lod->lod->seam_vertices.size() : 0;
  const size_t seam_triangles = m.triangle_count() - triangles;
  Header h;
  h.lod = lod != nullptr;
  h.cells = cells;
  h.vertices = vertices;
  h.triangles = triangles;
  h.dropped = dropped;
  if (lod != nullptr) {
    h.seams = lod->seams;
    h.seam_vertices = static_cast<uint32_t>(seam_vertices);
    h.seam_triangles = static_cast<uint32_t>(seam_triangles);
  }
  const size_t header = h.bytes();
  const size_t seam_bytes = kSeamVertexBytes * seam_vertices + 12 * seam_triangles;
  const size_t size = header + (rows + 7) / 8 + nonzero * rb + 5 * size_t{vertices} +
                      4 * size_t{dropped} + seam_bytes + kChecksumBytes;
  out.resize(size);
  uint8_t* p = out.data();
  write_header(h, p);
  // The rows and vertex planes of a level-of-detail chunk's variants are the same (their
  // regular vertices are): written once per vertex pass, then copied.
  const size_t shared = (rows + 7) / 8 + nonzero * rb + 5 * size_t{vertices};
  const bool cached = lod != nullptr && lod->vertex_pass != 0 && scratch.shared_of == lod->lod &&
                      scratch.shared_pass == lod->vertex_pass && scratch.shared.size() == shared;
  if (cached) {
    p = std::copy(scratch.shared.begin(), scratch.shared.end(), p + header);
  } else {
    uint8_t* const from = p + header;
    p = write_rows(scratch.row_diff, rows, rb, from);
    p = write_vertex_planes(m, t, cells, vertices, p);
    if (lod != nullptr) {
      scratch.shared.assign(from, p);
      scratch.shared_of = lod->lod;
      scratch.shared_pass = lod->vertex_pass;
    }
  }
  for (uint32_t d : scratch.triangles) {
    put_u32(p, d);
    p += 4;
  }
  if (lod != nullptr) write_seam_section(m, *lod->lod, p);
  put_u32(out.data() + size - kChecksumBytes, crc32c(out.data(), size - kChecksumBytes));
}

}  // namespace

void encode_mesh(const mesh::ChunkMesh& m, const mesh::MeshScratch& t,
                 const std::array<int, 3>& cells, CodecScratch& scratch, Bytes& out) {
  encode_impl(m, t, cells, nullptr, scratch, out);
}

void encode_lod_mesh(const mesh::ChunkMesh& m, const mesh::LodScratch& lod, CodecScratch& scratch,
                     Bytes& out, uint64_t vertex_pass) {
  const LodSection section{lod.seams, &lod.seam_cells, &lod, vertex_pass};
  encode_impl(m, lod.mc, {32, 32, 32}, &section, scratch, out);
}

namespace {

// Format 2's seam vertices and triangles, appended to the regular part in m.
std::optional<Error> read_seam_section(const uint8_t* p, uint32_t count, uint32_t triangles,
                                       mesh::ChunkMesh& m) {
  const auto regular = static_cast<uint32_t>(m.vertex_count());
  const uint8_t* plane[kSeamVertexBytes];
  for (size_t k = 0; k < kSeamVertexBytes; ++k) plane[k] = p + k * count;
  uint8_t material = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const int h[3] = {plane[0][i], plane[1][i], plane[2][i]};
    const int axis = plane[3][i];
    const unsigned q = plane[4][i] | static_cast<unsigned>(plane[5][i]) << 8;
    if (axis > 2 || h[0] > 64 || h[1] > 64 || h[2] > 64 || h[axis] >= 64)
      return Error{"seam vertex edge outside the chunk"};
    if (q > kFractionSteps) return Error{"edge fraction over 1024"};
    mesh::Vec3f pos{static_cast<float>(h[0]) * 0.5f, static_cast<float>(h[1]) * 0.5f,
                    static_cast<float>(h[2]) * 0.5f};
    (&pos.x)[axis] += static_cast<float>(q) * (1.0f / (2 * kFractionSteps));
    material = static_cast<uint8_t>(material + plane[8][i]);
    m.positions.push_back(pos);
    m.normals.push_back(decode_normal_inline(plane[6][i], plane[7][i]));
    m.materials.push_back(material);
  }
  p += kSeamVertexBytes * size_t{count};
  const uint32_t total = regular + count;
  for (size_t k = 0; k < 3 * size_t{triangles}; ++k, p += 4) {
    const uint32_t v = get_u32(p);
    if (v >= total) return Error{"seam triangle names a vertex that does not exist"};
    m.indices.push_back(v);
  }
  return std::nullopt;
}

}  // namespace

namespace {

std::optional<Error> read_header(std::span<const uint8_t> in, const DecodeLimits& limits,
                                 Header& h) {
  if (in.size() > limits.max_encoding_bytes) return Error{"mesh encoding larger than the limit"};
  if (in.size() < kHeaderBytes + kChecksumBytes)
    return Error{"mesh encoding truncated (no header)"};
  if (in[0] != kMeshFormat && in[0] != kLodMeshFormat)
    return Error{"unknown mesh format " + std::to_string(in[0])};
  if (in.size() < (in[0] == kLodMeshFormat ? kLodHeaderBytes : kHeaderBytes) + kChecksumBytes)
    return Error{"mesh encoding truncated (no header)"};
  h = parse_header(in);
  for (int c : h.cells) {
    if (c < 1 || c > 32) return Error{"cells per axis must be 1..32"};
    if (h.lod && c != 32) return Error{"a level-of-detail chunk has 32 cells per axis"};
  }
  if (h.vertices > kMaxVertices || h.triangles > kMaxTriangles || h.dropped > kMaxTriangles)
    return Error{"mesh encoding declares impossible counts"};
  if (h.lod) {
    if (h.seams.faces > 63 || h.seams.edges > 0xfff || world::normalized(h.seams) != h.seams)
      return Error{"seam faces and edges are not a normalized set"};
    if (h.seam_vertices > kMaxSeamVertices || h.seam_triangles > kMaxSeamTriangles)
      return Error{"mesh encoding declares impossible seam counts"};
  }
  if (crc32c(in.data(), in.size() - kChecksumBytes) !=
      get_u32(in.data() + in.size() - kChecksumBytes)) {
    return Error{"mesh encoding checksum mismatch (corrupt, or a delta against the wrong base)"};
  }
  return std::nullopt;
}

// The solid rows from the bitmap and differences at p, into t.solid; p moves past them.
std::optional<Error> read_rows(const uint8_t* flags, size_t bitmap, const std::array<int, 3>& cells,
                               mesh::MeshScratch& t, const uint8_t*& p) {
  const size_t rb = row_bytes(cells[0]);
  const uint64_t valid = mesh::detail::low_bits(cells[0] + 1);
  uint64_t previous = 0;
  size_t r = 0;
  p = flags + bitmap;
  for (int z = 0; z <= cells[2]; ++z) {
    for (int y = 0; y <= cells[1]; ++y, ++r) {
      if ((flags[r / 8] >> (r % 8)) & 1) {
        uint64_t x = 0;
        for (size_t b = 0; b < rb; ++b) x |= static_cast<uint64_t>(p[b]) << (8 * b);
        p += rb;
        if (x == 0 || (x & ~valid)) return Error{"solid row is zero or has bits beyond the chunk"};
        previous ^= x;
      }
      t.solid[row_of(y, z)] = previous;
    }
  }
  return std::nullopt;
}

// The five vertex planes at p (V bytes each) into m's positions, normals and materials.
std::optional<Error> read_vertex_planes(const uint8_t* p, const mesh::MeshScratch& t,
                                        const std::array<int, 3>& cells, uint32_t vertices,
                                        mesh::ChunkMesh& m) {
  const uint8_t* frac_lo = p;
  const uint8_t* frac_hi = frac_lo + vertices;
  const uint8_t* nu = frac_hi + vertices;
  const uint8_t* nv = nu + vertices;
  const uint8_t* mat = nv + vertices;
  m.positions.resize(vertices);
  m.normals.resize(vertices);
  m.materials.resize(vertices);
  // Raw pointers: byte stores may alias anything, so vector members would be reloaded.
  mesh::Vec3f* out_pos = m.positions.data();
  mesh::Vec3f* out_nrm = m.normals.data();
  uint8_t* out_mat = m.materials.data();
  bool bad_fraction = false;
  for_each_vertex(t, cells, [&](uint32_t i, int a, int x, int y, int z) {
    const unsigned q = frac_lo[i] | static_cast<unsigned>(frac_hi[i]) << 8;
    bad_fraction |= q > kFractionSteps;
    const float f = static_cast<float>(q) * (1.0f / kFractionSteps);
    // Selects instead of indexing a member by axis, which would force pos through memory.
    out_pos[i] = {static_cast<float>(x) + (a == 0 ? f : 0.0f),
                  static_cast<float>(y) + (a == 1 ? f : 0.0f),
                  static_cast<float>(z) + (a == 2 ? f : 0.0f)};
  });
  if (bad_fraction) return Error{"edge fraction over 1024"};
  // Normals and materials do not depend on the edge: plain loops.
  for (uint32_t i = 0; i < vertices; ++i) out_nrm[i] = decode_normal_inline(nu[i], nv[i]);
  uint8_t material = 0;
  for (uint32_t i = 0; i < vertices; ++i) {
    material = static_cast<uint8_t>(material + mat[i]);
    out_mat[i] = material;
  }
  return std::nullopt;
}

// Every table triangle of the mixed cells (seam cells left out), minus the dropped
// ordinals listed at `drop`.
std::optional<Error> read_triangles(const uint8_t* drop, const Header& h, CodecScratch& scratch,
                                    mesh::ChunkMesh& m) {
  uint32_t previous_drop = 0;
  for (uint32_t k = 0; k < h.dropped; ++k) {
    const uint32_t d = get_u32(drop + 4 * k);
    if (k > 0 && d <= previous_drop) return Error{"dropped triangle list out of order"};
    previous_drop = d;
  }
  // The buffer holds the declared table triangles; a mixed-cell pattern that yields more
  // is refused instead of written past the end.
  const size_t declared = size_t{h.triangles} + h.dropped;
  m.indices.resize(declared * 3);
  uint32_t ordinal = 0, next_drop = 0;
  const mesh::CellRows* skip = nullptr;
  if (h.lod) {
    mesh::seam_cell_rows(h.seams, scratch.seam_cells);
    skip = &scratch.seam_cells;
  }
  const size_t written = mesh::emit_triangles(
      scratch.topology, h.cells, m.indices.data(),
      [&](uint32_t, uint32_t, uint32_t) {
        if (ordinal >= declared) {
          ++ordinal;
          return false;
        }
        const bool drop_it = next_drop < h.dropped && get_u32(drop + 4 * next_drop) == ordinal;
        next_drop += drop_it ? 1 : 0;
        ++ordinal;
        return !drop_it;
      },
      skip);
  if (ordinal != declared) return Error{"triangle count does not match the solid rows"};
  if (next_drop != h.dropped) return Error{"dropped triangle beyond the last triangle"};
  if (written != h.triangles) return Error{"triangle count does not match the solid rows"};
  m.indices.resize(written * 3);
  return std::nullopt;
}

}  // namespace

std::optional<Error> decode_mesh(std::span<const uint8_t> in, const DecodeLimits& limits,
                                 CodecScratch& scratch, mesh::ChunkMesh& m) {
  m.clear();
  Header h;
  if (auto error = read_header(in, limits, h)) return error;
  const size_t rb = row_bytes(h.cells[0]);
  const size_t rows = static_cast<size_t>(h.cells[1] + 1) * static_cast<size_t>(h.cells[2] + 1);
  const size_t bitmap = (rows + 7) / 8;
  if (in.size() < h.bytes() + bitmap + kChecksumBytes)
    return Error{"mesh encoding truncated (row bitmap)"};
  const uint8_t* flags = in.data() + h.bytes();
  size_t nonzero = 0;
  for (size_t r = 0; r < rows; ++r) nonzero += (flags[r / 8] >> (r % 8)) & 1;
  for (size_t r = rows; r < bitmap * 8; ++r) {
    if ((flags[r / 8] >> (r % 8)) & 1) return Error{"row bitmap flags rows beyond the chunk"};
  }
  const size_t expected = h.bytes() + bitmap + nonzero * rb + 5 * size_t{h.vertices} +
                          4 * size_t{h.dropped} + kSeamVertexBytes * size_t{h.seam_vertices} +
                          12 * size_t{h.seam_triangles} + kChecksumBytes;
  if (in.size() != expected) return Error{"mesh encoding has the wrong length for its counts"};

  const uint8_t* p = nullptr;
  if (auto error = read_rows(flags, bitmap, h.cells, scratch.topology, p)) return error;
  if (mesh::index_cut_edges(scratch.topology, h.cells) != h.vertices)
    return Error{"vertex count does not match the solid rows"};
  if (auto error = read_vertex_planes(p, scratch.topology, h.cells, h.vertices, m)) return error;
  const uint8_t* drop = p + 5 * size_t{h.vertices};
  if (auto error = read_triangles(drop, h, scratch, m)) return error;
  if (h.lod)
    return read_seam_section(drop + 4 * size_t{h.dropped}, h.seam_vertices, h.seam_triangles, m);
  return std::nullopt;
}

Result<mesh::ChunkMesh> decode_mesh(std::span<const uint8_t> in, const DecodeLimits& limits,
                                    CodecScratch& scratch) {
  mesh::ChunkMesh m;
  if (auto error = decode_mesh(in, limits, scratch, m)) return *error;
  return m;
}

Result<mesh::ChunkMesh> decode_mesh(std::span<const uint8_t> encoding, const DecodeLimits& limits) {
  // On the heap: a thread_local of this size (66 KiB) is carved out of every thread's
  // stack, civetweb's small ones included, whose metrics handler then overflowed.
  static thread_local std::unique_ptr<CodecScratch> scratch;
  if (!scratch) scratch = std::make_unique<CodecScratch>();
  return decode_mesh(encoding, limits, *scratch);
}

}  // namespace vox::proto
