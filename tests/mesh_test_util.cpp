#include "tests/mesh_test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/marching_cubes_tables.hpp"
#include "server/mesh/position_key.hpp"

namespace vox::test {
namespace {

using mesh::Vec3f;

float dist2(const Vec3f& a, const Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

// Exact: the coordinates are multiples of 1/1024 and at most a voxel apart.
bool zero_area(const Triangle& t) {
  const double u[3] = {double{t[1].x} - t[0].x, double{t[1].y} - t[0].y, double{t[1].z} - t[0].z};
  const double w[3] = {double{t[2].x} - t[0].x, double{t[2].y} - t[0].y, double{t[2].z} - t[0].z};
  return u[1] * w[2] == u[2] * w[1] && u[2] * w[0] == u[0] * w[2] && u[0] * w[1] == u[1] * w[0];
}

float centroid_x(const Triangle& t) { return (t[0].x + t[1].x + t[2].x) / 3.0f; }

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  }
  void unite(uint32_t a, uint32_t b) { parent[find(a)] = find(b); }
};

}  // namespace

std::vector<Triangle> reference_marching_cubes(
    const std::function<world::Density(int, int, int)>& density, std::array<int, 3> lo,
    std::array<int, 3> hi) {
  std::vector<Triangle> out;
  for (int z = lo[2]; z < hi[2]; ++z) {
    for (int y = lo[1]; y < hi[1]; ++y) {
      for (int x = lo[0]; x < hi[0]; ++x) {
        int d[8];
        unsigned cube = 0;
        for (int c = 0; c < 8; ++c) {
          d[c] = density(x + mesh::kCubeCorner[c][0], y + mesh::kCubeCorner[c][1],
                         z + mesh::kCubeCorner[c][2]);
          if (d[c] > 0) cube |= 1u << c;
        }
        if (mesh::edgeTable[cube] == 0) continue;
        Vec3f vertex[12];
        for (int e = 0; e < 12; ++e) {
          if (!(mesh::edgeTable[cube] & (1u << e))) continue;
          int a = mesh::kEdgeCorners[e][0], b = mesh::kEdgeCorners[e][1];
          const auto& ca = mesh::kCubeCorner[a];
          const auto& cb = mesh::kCubeCorner[b];
          if (ca[0] + ca[1] + ca[2] > cb[0] + cb[1] + cb[2]) std::swap(a, b);  // a: lower end
          const float exact = static_cast<float>(d[a]) / static_cast<float>(d[a] - d[b]);
          const float t =
              std::round(exact * mesh::kFractionSteps) / mesh::kFractionSteps;  // the wire's step
          float p[3] = {static_cast<float>(x + mesh::kCubeCorner[a][0]),
                        static_cast<float>(y + mesh::kCubeCorner[a][1]),
                        static_cast<float>(z + mesh::kCubeCorner[a][2])};
          for (int k = 0; k < 3; ++k) {
            if (mesh::kCubeCorner[a][k] != mesh::kCubeCorner[b][k]) p[k] += t;
          }
          vertex[e] = {p[0], p[1], p[2]};
        }
        for (const int8_t* tri = mesh::triTable[cube].data(); *tri >= 0; tri += 3) {
          const Triangle t{vertex[tri[0]], vertex[tri[1]], vertex[tri[2]]};
          if (zero_area(t)) continue;
          out.push_back(t);
        }
      }
    }
  }
  return out;
}

std::vector<Triangle> world_triangles(const std::vector<mesh::ChunkMesh>& meshes,
                                      const mesh::ChunkBox& box) {
  std::vector<Triangle> out;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const world::ChunkCoord c = box.at(i);
    const Vec3f o{static_cast<float>(c.x * world::kChunkSize),
                  static_cast<float>(c.y * world::kChunkSize),
                  static_cast<float>(c.z * world::kChunkSize)};
    const auto& m = meshes[i];
    for (size_t k = 0; k < m.indices.size(); k += 3) {
      Triangle t;
      for (int j = 0; j < 3; ++j) {
        const Vec3f p = m.positions[m.indices[k + j]];
        t[j] = {p.x + o.x, p.y + o.y, p.z + o.z};
      }
      out.push_back(t);
    }
  }
  return out;
}

std::vector<Triangle> world_triangles(const mesh::ChunkMesh& m) {
  std::vector<Triangle> out;
  for (size_t k = 0; k < m.indices.size(); k += 3) {
    out.push_back(
        {m.positions[m.indices[k]], m.positions[m.indices[k + 1]], m.positions[m.indices[k + 2]]});
  }
  return out;
}

size_t unmatched_triangles(const std::vector<Triangle>& a, const std::vector<Triangle>& b,
                           float tolerance) {
  std::vector<Triangle> sorted = b;
  std::sort(sorted.begin(), sorted.end(),
            [](const Triangle& l, const Triangle& r) { return centroid_x(l) < centroid_x(r); });
  std::vector<bool> used(sorted.size(), false);
  const float tol2 = tolerance * tolerance;
  size_t unmatched = 0;
  for (const Triangle& t : a) {
    const float cx = centroid_x(t);
    auto it = std::lower_bound(sorted.begin(), sorted.end(), cx - 2 * tolerance,
                               [](const Triangle& l, float v) { return centroid_x(l) < v; });
    bool found = false;
    for (; it != sorted.end() && centroid_x(*it) <= cx + 2 * tolerance && !found; ++it) {
      const size_t j = static_cast<size_t>(it - sorted.begin());
      if (used[j]) continue;
      for (int r = 0; r < 3 && !found; ++r) {
        if (dist2(t[0], (*it)[r]) <= tol2 && dist2(t[1], (*it)[(r + 1) % 3]) <= tol2 &&
            dist2(t[2], (*it)[(r + 2) % 3]) <= tol2) {
          used[j] = true;
          found = true;
        }
      }
    }
    if (!found) ++unmatched;
  }
  return unmatched;
}

Topology analyse(const mesh::ChunkMesh& m) {
  std::unordered_map<mesh::PositionKey, uint32_t, mesh::PositionKeyHash> ids;
  std::vector<uint32_t> id_of(m.vertex_count());
  std::vector<Vec3f> position_of_id;
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const Vec3f p = m.positions[v];
    auto [it, inserted] = ids.try_emplace(mesh::position_key(p), static_cast<uint32_t>(ids.size()));
    if (inserted) position_of_id.push_back(p);
    id_of[v] = it->second;
  }
  Topology topo;
  std::map<std::pair<uint32_t, uint32_t>, std::pair<int, int>>
      edges;  // (lo, hi) -> (lo->hi uses, hi->lo uses)
  UnionFind uf(ids.size());
  std::vector<bool> used(ids.size(), false);
  for (size_t k = 0; k < m.indices.size(); k += 3) {
    const uint32_t v[3] = {id_of[m.indices[k]], id_of[m.indices[k + 1]], id_of[m.indices[k + 2]]};
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) continue;
    ++topo.faces;
    const Vec3f a = m.positions[m.indices[k]], b = m.positions[m.indices[k + 1]],
                c = m.positions[m.indices[k + 2]];
    const double ux = b.x - a.x, uy = b.y - a.y, uz = b.z - a.z, wx = c.x - a.x, wy = c.y - a.y,
                 wz = c.z - a.z;
    const double nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
    topo.area += 0.5 * std::sqrt(nx * nx + ny * ny + nz * nz);
    topo.volume += (a.x * (static_cast<double>(b.y) * c.z - static_cast<double>(b.z) * c.y) -
                    a.y * (static_cast<double>(b.x) * c.z - static_cast<double>(b.z) * c.x) +
                    a.z * (static_cast<double>(b.x) * c.y - static_cast<double>(b.y) * c.x)) /
                   6.0;
    for (int e = 0; e < 3; ++e) {
      const uint32_t from = v[e], to = v[(e + 1) % 3];
      auto& uses = edges[{std::min(from, to), std::max(from, to)}];
      (from < to ? uses.first : uses.second)++;
      uf.unite(from, to);
      used[from] = true;
    }
  }
  topo.edges = edges.size();
  for (const auto& [key, uses] : edges) {
    const int total = uses.first + uses.second;
    if (total == 1) {
      ++topo.boundary_edges;
      topo.open_edges.push_back({position_of_id[key.first], position_of_id[key.second]});
    }
    if (total > 2) {
      ++topo.non_manifold_edges;
      topo.crowded_edges.push_back({position_of_id[key.first], position_of_id[key.second]});
    }
    if (total == 2 && uses.first != 1) ++topo.misoriented_edges;
  }
  for (uint32_t v = 0; v < used.size(); ++v) {
    if (!used[v]) continue;
    ++topo.vertices;
    if (uf.find(v) == v) ++topo.components;
  }
  return topo;
}

void expect_closed_manifold(const Topology& t) {
  EXPECT_GT(t.faces, 0u);
  EXPECT_EQ(t.boundary_edges, 0u);
  EXPECT_EQ(t.non_manifold_edges, 0u);
  EXPECT_EQ(t.misoriented_edges, 0u);
  EXPECT_EQ(t.euler(), 2 * static_cast<long>(t.components)) << "genus-0 components expected";
  EXPECT_GT(t.volume, 0.0) << "normals must point out of the solid";
  for (size_t i = 0; i < t.open_edges.size() && i < 5; ++i) {
    const auto& e = t.open_edges[i];
    ADD_FAILURE() << "open edge (" << e[0].x << ", " << e[0].y << ", " << e[0].z << ") - ("
                  << e[1].x << ", " << e[1].y << ", " << e[1].z << ")";
  }
}

void fill_from_field(world::ChunkMap& map, const mesh::ChunkBox& box,
                     const std::function<float(float, float, float)>& field,
                     world::Material material) {
  for (int cz = box.lo.z - 1; cz <= box.hi.z + 1; ++cz) {
    for (int cy = box.lo.y - 1; cy <= box.hi.y + 1; ++cy) {
      for (int cx = box.lo.x - 1; cx <= box.hi.x + 1; ++cx) {
        world::Chunk chunk;
        world::Density* d = chunk.densities();
        world::Material* mt = chunk.materials();
        for (int z = 0; z < world::kChunkSize; ++z)
          for (int y = 0; y < world::kChunkSize; ++y)
            for (int x = 0; x < world::kChunkSize; ++x) {
              const int i = world::Chunk::index(x, y, z);
              d[i] = world::quantize_density(field(static_cast<float>(cx * world::kChunkSize + x),
                                                   static_cast<float>(cy * world::kChunkSize + y),
                                                   static_cast<float>(cz * world::kChunkSize + z)));
              mt[i] = world::is_solid(d[i]) ? material : world::kAir;
            }
        chunk.compact();
        map.insert({cx, cy, cz}, std::move(chunk));
      }
    }
  }
}

}  // namespace vox::test
