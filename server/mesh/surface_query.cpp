#include "server/mesh/surface_query.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "server/mesh/edge_vertex.hpp"
#include "server/mesh/marching_cubes_tables.hpp"

namespace vox::mesh {

using world::ChunkCoord;

namespace {

// Reads samples at world voxel coordinates, keeping the last chunk it looked up. Once the
// source gave up, every sample reads as air and failed() is true.
class SampleReader {
 public:
  explicit SampleReader(ChunkSource& chunks) : chunks_(chunks) {}
  world::Sample at(int32_t x, int32_t y, int32_t z) {
    if (failed_) return {};
    const ChunkCoord c = world::chunk_of_voxel(x, y, z);
    if (!(c == last_)) {
      last_ = c, chunk_ = chunks_.chunk(c);
      failed_ = chunk_ == nullptr;
      if (failed_) return {};
    }
    const int32_t k = world::kChunkSize;
    return chunk_->at(world::floor_mod(x, k), world::floor_mod(y, k), world::floor_mod(z, k));
  }
  bool failed() const { return failed_; }

 private:
  ChunkSource& chunks_;
  ChunkCoord last_{INT32_MIN, INT32_MIN, INT32_MIN};
  const world::Chunk* chunk_ = nullptr;
  bool failed_ = false;
};

// The cells along the ray, nearest first (Amanatides & Woo), while fn(cell, t_in, t_out)
// returns true and the cell starts within max_distance.
template <class Fn>
void walk_cells(const Ray& ray, Fn&& fn) {
  const double o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  const double d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  int32_t cell[3];
  int step[3];
  double t_next[3], t_delta[3];
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    cell[a] = static_cast<int32_t>(std::floor(o[a]));
    if (d[a] > 0) {
      step[a] = 1, t_delta[a] = 1 / d[a], t_next[a] = (cell[a] + 1 - o[a]) / d[a];
    } else if (d[a] < 0) {
      step[a] = -1, t_delta[a] = -1 / d[a], t_next[a] = (cell[a] - o[a]) / d[a];
    } else {
      step[a] = 0, t_delta[a] = kInf, t_next[a] = kInf;
    }
  }
  double t = 0;
  while (t <= ray.max_distance) {
    const int a = t_next[0] <= t_next[1] ? (t_next[0] <= t_next[2] ? 0 : 2)
                                         : (t_next[1] <= t_next[2] ? 1 : 2);
    const double t_out = t_next[a];
    if (!fn(cell, t, t_out)) return;
    t = t_out;
    cell[a] += step[a];
    t_next[a] += t_delta[a];
  }
}

// Möller & Trumbore: the distance along the ray to the triangle and the weights of p1, p2.
bool intersect(const double (&o)[3], const double (&d)[3], const std::array<double, 3>& p0,
               const std::array<double, 3>& p1, const std::array<double, 3>& p2, double& t,
               double& u, double& v) {
  const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
  const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                       d[0] * e2[1] - d[1] * e2[0]};
  const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
  if (std::abs(det) < 1e-12) return false;  // parallel, or no area
  const double inv = 1 / det;
  const double s[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
  u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) * inv;
  constexpr double kEdge = 1e-7;  // a ray along a shared edge hits one of its triangles
  if (u < -kEdge || u > 1 + kEdge) return false;
  const double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                       s[0] * e1[1] - s[1] * e1[0]};
  v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
  if (v < -kEdge || u + v > 1 + kEdge) return false;
  t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
  return true;
}

}  // namespace

RayHit raycast(ChunkSource& chunks, const Ray& ray) {
  SampleReader read(chunks);
  const double o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  const double d[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
  RayHit best;
  // The samples around a cell: corners at 1..2 of a 4^3 block, their neighbours at 0 and 3.
  std::array<world::Density, 64> dens;
  std::array<world::Material, 64> mats;
  constexpr GridStrides kStride = {1, 4, 16};
  walk_cells(ray, [&](const int32_t(&cell)[3], double t_in, double t_out) {
    int solid = 0;
    for (int c = 0; c < 8; ++c) {
      const auto& k = kCubeCorner[c];
      solid |= world::is_solid(read.at(cell[0] + k[0], cell[1] + k[1], cell[2] + k[2]).density)
                   ? 1 << c
                   : 0;
    }
    if (read.failed()) {
      best.complete = false, best.distance = static_cast<float>(t_in);
      return false;
    }
    if (solid == 0 || solid == 255) return true;
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) {
          const world::Sample s = read.at(cell[0] + x - 1, cell[1] + y - 1, cell[2] + z - 1);
          dens[x + 4 * y + 16 * z] = s.density;
          mats[x + 4 * y + 16 * z] = s.material;
        }
    if (read.failed()) {
      best.complete = false, best.distance = static_cast<float>(t_in);
      return false;
    }
    // The cut edges' vertices, as the mesher makes them.
    std::array<std::array<double, 3>, 12> pos;
    std::array<EdgeVertex, 12> vertex;
    const uint16_t cut = edgeTable[solid];
    for (int e = 0; e < 12; ++e) {
      if (!(cut & (1 << e))) continue;
      const EdgeSlot& slot = kEdgeSlot[e];
      const int lower[3] = {slot.dx, slot.dy, slot.dz};
      const int i0 = (lower[0] + 1) + 4 * (lower[1] + 1) + 16 * (lower[2] + 1);
      vertex[e] = edge_vertex(dens.data(), mats.data(), i0, slot.axis, kStride, 0);
      for (int c = 0; c < 3; ++c) pos[e][c] = static_cast<double>(cell[c]) + lower[c];
      pos[e][slot.axis] += edge_offset(vertex[e].fraction);
    }
    double near = std::numeric_limits<double>::infinity(), wu = 0, wv = 0;
    int tri[3] = {};
    for (int i = 0; i < 15 && triTable[solid][i] >= 0; i += 3) {
      const int e0 = triTable[solid][i], e1 = triTable[solid][i + 1], e2 = triTable[solid][i + 2];
      double t, u, v;
      if (!intersect(o, d, pos[e0], pos[e1], pos[e2], t, u, v)) continue;
      constexpr double kSlack = 1e-6;
      if (t < std::max(0.0, t_in - kSlack) || t > t_out + kSlack || t > ray.max_distance) continue;
      if (t < near) near = t, wu = u, wv = v, tri[0] = e0, tri[1] = e1, tri[2] = e2;
    }
    if (!std::isfinite(near)) return true;
    best.hit = true;
    best.distance = static_cast<float>(near);
    best.point = {static_cast<float>(o[0] + near * d[0]), static_cast<float>(o[1] + near * d[1]),
                  static_cast<float>(o[2] + near * d[2])};
    const double w[3] = {1 - wu - wv, wu, wv};
    double n[3] = {};
    int nearest = 0;
    for (int j = 0; j < 3; ++j) {
      const Vec3f& vn = vertex[tri[j]].normal;
      n[0] += w[j] * vn.x, n[1] += w[j] * vn.y, n[2] += w[j] * vn.z;
      if (w[j] > w[nearest]) nearest = j;
    }
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0)
      best.normal = {static_cast<float>(n[0] / len), static_cast<float>(n[1] / len),
                     static_cast<float>(n[2] / len)};
    else
      best.normal = vertex[tri[nearest]].normal;
    best.material = vertex[tri[nearest]].material;
    return false;
  });
  return best;
}

bool read_samples(ChunkSource& chunks, const world::VoxelBox& box, std::string& densities,
                  std::string& materials) {
  size_t n = 1;
  for (int a = 0; a < 3; ++a) n *= static_cast<size_t>(int64_t{box.hi[a]} - box.lo[a] + 1);
  densities.resize(2 * n);
  materials.resize(n);
  const int32_t k = world::kChunkSize;
  size_t i = 0;
  for (int32_t z = box.lo[2]; z <= box.hi[2]; ++z)
    for (int32_t y = box.lo[1]; y <= box.hi[1]; ++y)
      for (int32_t x = box.lo[0]; x <= box.hi[0];) {  // a run within one chunk at a time
        const ChunkCoord c = world::chunk_of_voxel(x, y, z);
        const world::Chunk* chunk = chunks.chunk(c);
        if (!chunk) return false;
        const int32_t end = std::min(box.hi[0], c.x * k + k - 1);
        const int ly = world::floor_mod(y, k), lz = world::floor_mod(z, k);
        for (; x <= end; ++x, ++i) {
          const world::Sample s = chunk->at(x - c.x * k, ly, lz);
          const auto u = static_cast<uint16_t>(s.density);
          densities[2 * i] = static_cast<char>(u & 0xff);
          densities[2 * i + 1] = static_cast<char>(u >> 8);
          materials[i] = static_cast<char>(s.material);
        }
      }
  return true;
}

}  // namespace vox::mesh
