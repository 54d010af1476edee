#include "mesh/mesh_welder.hpp"

#include <bit>
#include <cassert>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "world/chunk_coord.hpp"
#include "world/parallel.hpp"

namespace vox::mesh {
namespace {

constexpr float kFace = static_cast<float>(world::kChunkSize);

struct Key {
  uint32_t x, y, z;
  bool operator==(const Key&) const = default;
};
struct KeyHash {
  size_t operator()(const Key& k) const noexcept {
    uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
    h ^= (h >> 32) ^ (k.y * 0xC2B2AE3D27D4EB4Full);
    h ^= (h >> 29) ^ (k.z * 0x165667B19E3779F9ull);
    return static_cast<size_t>(h ^ (h >> 31));
  }
};
Key key_of(const Vec3f& w) {
  return {std::bit_cast<uint32_t>(w.x), std::bit_cast<uint32_t>(w.y), std::bit_cast<uint32_t>(w.z)};
}
bool on_face(const Vec3f& l) {
  return l.x == 0.0f || l.y == 0.0f || l.z == 0.0f || l.x == kFace || l.y == kFace || l.z == kFace;
}

struct Grid {
  std::array<int, 3> dims;
  Vec3f origin;

  std::array<int, 3> pos(size_t i) const {
    return {static_cast<int>(i % dims[0]), static_cast<int>(i / dims[0] % dims[1]),
            static_cast<int>(i / dims[0] / dims[1])};
  }
  size_t index(const std::array<int, 3>& g) const {
    return static_cast<size_t>(g[0]) + static_cast<size_t>(dims[0]) * (g[1] + static_cast<size_t>(dims[1]) * g[2]);
  }
  Vec3f world(size_t i, const Vec3f& l) const {
    const auto g = pos(i);
    return {origin.x + kFace * static_cast<float>(g[0]) + l.x, origin.y + kFace * static_cast<float>(g[1]) + l.y,
            origin.z + kFace * static_cast<float>(g[2]) + l.z};
  }
};

// Per vertex of a part: its number among the part's kept vertices, or kForeignBit | its
// entry in `foreign` (kept by another vertex).
constexpr uint32_t kForeignBit = 1u << 31;
struct Foreign {
  uint32_t part, vertex;  // the copy that is kept
  uint32_t global = 0;    // its index in the welded mesh
};
struct PartPlan {
  std::vector<uint32_t> local;
  std::vector<uint32_t> kept;  // vertex numbers of the kept vertices, in order
  std::vector<Foreign> foreign;
  std::unordered_map<Key, uint32_t, KeyHash> face;  // face vertices by world position: the first one
};

// Pass 1, one part: its face vertices by position.
void find_face_vertices(const Grid& grid, size_t i, const ChunkMesh& p, PartPlan& plan) {
  plan.local.resize(p.vertex_count());
  for (uint32_t v = 0; v < p.vertex_count(); ++v) {
    if (on_face(p.positions[v])) plan.face.try_emplace(key_of(grid.world(i, p.positions[v])), v);
  }
}

// The copy of face vertex `l` (local to part i) that is kept: that of the first part
// holding a copy, trying first the chunk where its face coordinates are 0, then
// the chunks below it on those axes. Every part holding it tries the same chunks in the
// same order, so all agree; a missing or empty neighbour just does not hold it.
Foreign owner_of(const Grid& grid, std::span<const PartPlan> plans, size_t i, const Vec3f& l, const Key& key) {
  const auto g = grid.pos(i);
  const float c[3] = {l.x, l.y, l.z};
  std::array<int, 3> home{};
  unsigned on = 0;
  for (int a = 0; a < 3; ++a) {
    home[a] = g[a] + (c[a] == kFace ? 1 : 0);
    on |= (c[a] == 0.0f || c[a] == kFace) ? 1u << a : 0u;
  }
  for (unsigned e = 0; e < 8; ++e) {
    if ((e & ~on) != 0) continue;
    std::array<int, 3> h = home;
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      h[a] -= (e >> a) & 1;
      inside &= h[a] >= 0 && h[a] < grid.dims[a];
    }
    if (!inside) continue;
    const size_t j = grid.index(h);
    const auto it = plans[j].face.find(key);
    if (it != plans[j].face.end()) return {static_cast<uint32_t>(j), it->second};
  }
  assert(false && "a face vertex is held by its own part");
  return {static_cast<uint32_t>(i), 0};
}

// Pass 2, one part: which vertices it keeps; the others point at the kept copy.
void plan_part(const Grid& grid, std::span<const PartPlan> plans, size_t i, const ChunkMesh& p, PartPlan& plan) {
  for (uint32_t v = 0; v < p.vertex_count(); ++v) {
    const Vec3f l = p.positions[v];
    if (on_face(l)) {
      const Foreign owner = owner_of(grid, plans, i, l, key_of(grid.world(i, l)));
      if (owner.part != i || owner.vertex != v) {
        plan.local[v] = kForeignBit | static_cast<uint32_t>(plan.foreign.size());
        plan.foreign.push_back(owner);
        continue;
      }
    }
    plan.local[v] = static_cast<uint32_t>(plan.kept.size());
    plan.kept.push_back(v);
  }
}

// Pass 3, one part: its kept vertices in world space, its triangles with welded indices.
void write_part(const Grid& grid, std::span<const PartPlan> plans, std::span<const size_t> vertex_base, size_t i,
                const ChunkMesh& p, PartPlan& plan, ChunkMesh& out, size_t index_base) {
  for (Foreign& f : plan.foreign) {
    assert(plans[f.part].local[f.vertex] < kForeignBit);
    f.global = static_cast<uint32_t>(vertex_base[f.part] + plans[f.part].local[f.vertex]);
  }
  const size_t base = vertex_base[i];
  for (size_t k = 0; k < plan.kept.size(); ++k) {
    const uint32_t v = plan.kept[k];
    out.positions[base + k] = grid.world(i, p.positions[v]);
    out.normals[base + k] = p.normals[v];
    out.materials[base + k] = p.materials[v];
  }
  uint32_t* dst = out.indices.data() + index_base;
  for (uint32_t index : p.indices) {
    const uint32_t l = plan.local[index];
    *dst++ = (l & kForeignBit) != 0 ? plan.foreign[l & ~kForeignBit].global : static_cast<uint32_t>(base + l);
  }
}

}  // namespace

ChunkMesh weld_chunk_grid(std::span<const ChunkMesh> parts, std::array<int, 3> grid_dims, Vec3f origin, int threads) {
  const size_t n = parts.size();
  const Grid grid{grid_dims, origin};
  std::vector<PartPlan> plans(n);
  tbb::task_arena arena(arena_concurrency(threads));
  parallel_for_index(arena, n, [&](size_t i) { find_face_vertices(grid, i, parts[i], plans[i]); });
  parallel_for_index(arena, n, [&](size_t i) { plan_part(grid, plans, i, parts[i], plans[i]); });

  std::vector<size_t> vertex_base(n + 1, 0), index_base(n + 1, 0);
  for (size_t i = 0; i < n; ++i) {
    vertex_base[i + 1] = vertex_base[i] + plans[i].kept.size();
    index_base[i + 1] = index_base[i] + parts[i].indices.size();
  }
  ChunkMesh out;
  out.positions.resize(vertex_base[n]);
  out.normals.resize(vertex_base[n]);
  out.materials.resize(vertex_base[n]);
  out.indices.resize(index_base[n]);
  parallel_for_index(arena, n, [&](size_t i) {
    write_part(grid, plans, vertex_base, i, parts[i], plans[i], out, index_base[i]);
  });
  return out;
}

}  // namespace vox::mesh
