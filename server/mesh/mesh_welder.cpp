#include "mesh/mesh_welder.hpp"

#include <bit>
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
Key key_of(const Vec3f& w) { return {std::bit_cast<uint32_t>(w.x), std::bit_cast<uint32_t>(w.y), std::bit_cast<uint32_t>(w.z)}; }

// Per chunk: for each vertex, its index among the chunk's own vertices, or kForeign when a
// neighbour owns it; the owned face vertices by world position, for the neighbours.
constexpr uint32_t kForeign = UINT32_MAX;
struct PartPlan {
  std::vector<uint32_t> local;
  std::vector<uint32_t> owned;  // vertex numbers of the owned vertices, in order
  std::unordered_map<Key, uint32_t, KeyHash> face_owned;
};

}  // namespace

ChunkMesh weld_chunk_grid(std::span<const ChunkMesh> parts, std::array<int, 3> grid, Vec3f origin, int threads) {
  const size_t n = parts.size();
  auto grid_pos = [&](size_t i) {
    return std::array<int, 3>{static_cast<int>(i % grid[0]), static_cast<int>(i / grid[0] % grid[1]),
                              static_cast<int>(i / grid[0] / grid[1])};
  };
  auto chunk_origin = [&](size_t i) {
    const auto g = grid_pos(i);
    return Vec3f{origin.x + kFace * static_cast<float>(g[0]), origin.y + kFace * static_cast<float>(g[1]),
                 origin.z + kFace * static_cast<float>(g[2])};
  };
  auto world_of = [](const Vec3f& l, const Vec3f& o) { return Vec3f{l.x + o.x, l.y + o.y, l.z + o.z}; };

  std::vector<PartPlan> plans(n);
  tbb::task_arena arena(arena_concurrency(threads));
  ChunkMesh out;
  std::vector<size_t> vertex_base(n + 1, 0), index_base(n + 1, 0);
  {
    // 1. Which vertices each chunk owns.
    parallel_for_index(arena, n, [&](size_t i) {
      const ChunkMesh& p = parts[i];
      PartPlan& plan = plans[i];
      const auto g = grid_pos(i);
      const Vec3f o = chunk_origin(i);
      plan.local.resize(p.vertex_count());
      for (size_t v = 0; v < p.vertex_count(); ++v) {
        const Vec3f l = p.positions[v];
        const bool foreign = (l.x == kFace && g[0] + 1 < grid[0]) || (l.y == kFace && g[1] + 1 < grid[1]) ||
                             (l.z == kFace && g[2] + 1 < grid[2]);
        if (foreign) {
          plan.local[v] = kForeign;
          continue;
        }
        plan.local[v] = static_cast<uint32_t>(plan.owned.size());
        plan.owned.push_back(static_cast<uint32_t>(v));
        if (l.x == 0.0f || l.y == 0.0f || l.z == 0.0f) plan.face_owned.try_emplace(key_of(world_of(l, o)), plan.local[v]);
      }
    });
    for (size_t i = 0; i < n; ++i) {
      vertex_base[i + 1] = vertex_base[i] + plans[i].owned.size();
      index_base[i + 1] = index_base[i] + parts[i].indices.size();
    }
    out.positions.resize(vertex_base[n]);
    out.normals.resize(vertex_base[n]);
    out.materials.resize(vertex_base[n]);
    out.indices.resize(index_base[n]);
    // 2. Copy owned vertices; point foreign ones at their owner's copy; remap indices.
    parallel_for_index(arena, n, [&](size_t i) {
      const ChunkMesh& p = parts[i];
      PartPlan& plan = plans[i];
      const auto g = grid_pos(i);
      const Vec3f o = chunk_origin(i);
      std::vector<uint32_t>& global = plan.local;  // rewritten in place to global indices
      for (size_t v = 0; v < p.vertex_count(); ++v) {
        const Vec3f l = p.positions[v];
        if (global[v] != kForeign) {
          const size_t at = vertex_base[i] + global[v];
          out.positions[at] = world_of(l, o);
          out.normals[at] = p.normals[v];
          out.materials[at] = p.materials[v];
          global[v] = static_cast<uint32_t>(at);
          continue;
        }
        const int dx = (l.x == kFace && g[0] + 1 < grid[0]) ? 1 : 0, dy = (l.y == kFace && g[1] + 1 < grid[1]) ? 1 : 0,
                  dz = (l.z == kFace && g[2] + 1 < grid[2]) ? 1 : 0;
        const size_t owner = i + dx + static_cast<size_t>(grid[0]) * (dy + static_cast<size_t>(grid[1]) * dz);
        const auto it = plans[owner].face_owned.find(key_of(world_of(l, o)));
        // Twins are bit-identical by construction of the mesher; a miss would be a crack.
        global[v] = it == plans[owner].face_owned.end() ? 0 : static_cast<uint32_t>(vertex_base[owner] + it->second);
      }
      uint32_t* dst = out.indices.data() + index_base[i];
      for (uint32_t index : p.indices) *dst++ = global[index];
    });
  }
  return out;
}

}  // namespace vox::mesh
