#include "server/mesh/mesh_welder.hpp"

#include <cassert>
#include <cmath>
#include <cstdint>
#include <vector>

#include "server/mesh/position_key.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/parallel.hpp"

namespace vox::mesh {
namespace {

constexpr float kFace = static_cast<float>(world::kChunkSize);

// Face vertices of one part by world position, first one kept: an open-addressing table
// in one array (linear probing, at most half full), built once from the collected
// entries (std::unordered_map's node per entry made welding a tenth slower).
class FaceTable {
 public:
  static constexpr uint32_t kNone = UINT32_MAX;
  void add(const PositionKey& k, uint32_t vertex) { pending_.push_back({k, vertex}); }
  void build() {
    if (pending_.empty()) {  // most chunks of a thin or empty volume: no table at all
      slots_.clear();
      return;
    }
    size_t capacity = 16;
    while (capacity < 2 * pending_.size()) capacity *= 2;
    slots_.assign(capacity, Slot{{}, kNone});
    mask_ = capacity - 1;
    for (const Slot& e : pending_) {
      size_t at = hash_of(e.key) & mask_;
      while (slots_[at].vertex != kNone && !(slots_[at].key == e.key)) at = (at + 1) & mask_;
      if (slots_[at].vertex == kNone) slots_[at] = e;  // the first vertex at a position stays
    }
    pending_ = {};
  }
  uint32_t find(const PositionKey& k) const {
    if (slots_.empty()) return kNone;
    for (size_t at = hash_of(k) & mask_;; at = (at + 1) & mask_) {
      if (slots_[at].vertex == kNone || slots_[at].key == k) return slots_[at].vertex;
    }
  }

 private:
  struct Slot {
    PositionKey key;
    uint32_t vertex;
  };
  std::vector<Slot> pending_, slots_;
  size_t mask_ = 0;
};

Vec3f add(const Vec3f& a, const Vec3f& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

// Where a vertex sits on its chunk's faces: bit a of `on` when its local coordinate a is 0
// or 32, of `upper` when it is 32; and whether it sits on a sample. Two vertices of one
// chunk can coincide only at a sample (different edges meet only there): a sample exactly
// on the iso level, or an edge fraction rounded to 0 or 1.
struct FacePlace {
  unsigned on = 0, upper = 0;
  bool at_sample = false;
};
inline FacePlace face_place(const Vec3f& l) {
  FacePlace f;
  f.at_sample = l.x == std::trunc(l.x) && l.y == std::trunc(l.y) && l.z == std::trunc(l.z);
  if (l.x != 0.0f && l.y != 0.0f && l.z != 0.0f && l.x != kFace && l.y != kFace && l.z != kFace)
    return f;
  const float c[3] = {l.x, l.y, l.z};
  for (unsigned a = 0; a < 3; ++a) {
    f.on |= (c[a] == 0.0f || c[a] == kFace) ? 1u << a : 0u;
    f.upper |= c[a] == kFace ? 1u << a : 0u;
  }
  return f;
}

struct Grid {
  std::array<int, 3> dims;
  Vec3f origin;

  std::array<int, 3> pos(size_t i) const {
    return {static_cast<int>(i % dims[0]), static_cast<int>(i / dims[0] % dims[1]),
            static_cast<int>(i / dims[0] / dims[1])};
  }
  size_t index(const std::array<int, 3>& g) const {
    return static_cast<size_t>(g[0]) +
           static_cast<size_t>(dims[0]) * (g[1] + static_cast<size_t>(dims[1]) * g[2]);
  }
  Vec3f origin_of(size_t i) const {
    const auto g = pos(i);
    return {origin.x + kFace * static_cast<float>(g[0]),
            origin.y + kFace * static_cast<float>(g[1]),
            origin.z + kFace * static_cast<float>(g[2])};
  }
};

// Per vertex of a part: its number among the part's kept vertices, kForeignBit | its
// entry in `foreign` (kept by another vertex), or kUnused (no triangle of the part uses it).
// Between passes 1 and 2: 0 for a used vertex the part keeps, kAsk for a used face
// vertex whose owner must be looked for.
constexpr uint32_t kUnused = UINT32_MAX;
constexpr uint32_t kAsk = UINT32_MAX - 1;
constexpr uint32_t kForeignBit = 1u << 31;
struct Foreign {
  uint32_t part, vertex;  // the copy that is kept
  uint32_t global = 0;    // its index in the welded mesh
};
struct PartPlan {
  std::vector<uint32_t> local;
  std::vector<uint32_t> kept;  // vertex numbers of the kept vertices, in order
  std::vector<Foreign> foreign;
  FaceTable face;  // used face vertices others may ask for: the first at each position
};

// Pass 1, one part: which vertices its triangles use; the used face vertices another
// part may ask for, by world position. A part is asked only by the holders after it in
// owner_of's order, so a vertex at 32 on every face axis it is on (the last holder) is
// left out unless it sits at a sample, where the part itself asks for its first copy. A
// vertex at a sample inside the chunk asks its own part for the first copy there too; any
// other vertex inside the chunk, or at its home away from a sample, is kept without asking.
void find_used_face_vertices(const Grid& grid, size_t i, const ChunkMesh& p, PartPlan& plan) {
  plan.local.assign(p.vertex_count(), kUnused);
  for (uint32_t index : p.indices) plan.local[index] = 0;
  const Vec3f o = grid.origin_of(i);
  for (uint32_t v = 0; v < p.vertex_count(); ++v) {
    if (plan.local[v] == kUnused) continue;
    const FacePlace f = face_place(p.positions[v]);
    if (f.on == 0 && !f.at_sample) continue;
    if (f.upper != f.on || f.at_sample) plan.face.add(position_key(add(o, p.positions[v])), v);
    if (f.upper != 0 || f.at_sample) plan.local[v] = kAsk;
  }
  plan.face.build();
}

// The copy of used face vertex v of part i that is kept: that of the first part holding a
// used copy, trying first the chunk where its face coordinates are 0 (its home), then the
// chunks below it on those axes. Every holder tries the same chunks in the same order, so
// all agree; a missing or empty neighbour just does not hold it.
Foreign owner_of(const Grid& grid, std::span<const PartPlan> plans, size_t i,
                 const std::array<int, 3>& g, uint32_t v, const FacePlace& f,
                 const PositionKey& key) {
  std::array<int, 3> home{};
  for (int a = 0; a < 3; ++a) home[a] = g[a] + static_cast<int>((f.upper >> a) & 1);
  for (unsigned e = 0; e < 8; ++e) {
    if ((e & ~f.on) != 0) continue;
    std::array<int, 3> h = home;
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      h[a] -= static_cast<int>((e >> a) & 1);
      inside &= h[a] >= 0 && h[a] < grid.dims[a];
    }
    if (!inside) continue;
    const size_t j = grid.index(h);
    const uint32_t u = plans[j].face.find(key);
    if (j == i) return {static_cast<uint32_t>(i), u != FaceTable::kNone ? u : v};
    if (u != FaceTable::kNone) return {static_cast<uint32_t>(j), u};
  }
  assert(false && "a used face vertex is held by its own part");
  return {static_cast<uint32_t>(i), v};
}

// Pass 2, one part: which used vertices it keeps; the others point at the kept copy.
void plan_part(const Grid& grid, std::span<const PartPlan> plans, size_t i, const ChunkMesh& p,
               PartPlan& plan) {
  const Vec3f o = grid.origin_of(i);
  const std::array<int, 3> g = grid.pos(i);
  for (uint32_t v = 0; v < p.vertex_count(); ++v) {
    if (plan.local[v] == kUnused) continue;
    if (plan.local[v] == kAsk) {
      const Vec3f l = p.positions[v];
      const Foreign owner = owner_of(grid, plans, i, g, v, face_place(l), position_key(add(o, l)));
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

// Pass 3, one part: the welded index of each copy it points at (read before any part
// rewrites its numbers in pass 4).
void resolve_foreign(std::span<const PartPlan> plans, std::span<const size_t> vertex_base,
                     PartPlan& plan) {
  for (Foreign& f : plan.foreign) {
    assert(plans[f.part].local[f.vertex] < kForeignBit);
    f.global = static_cast<uint32_t>(vertex_base[f.part] + plans[f.part].local[f.vertex]);
  }
}

// Pass 4, one part: its kept vertices in world space, its triangles with welded indices.
void write_part(const Grid& grid, size_t i, const ChunkMesh& p, PartPlan& plan, size_t vertex_base,
                ChunkMesh& out, size_t index_base) {
  const Vec3f o = grid.origin_of(i);
  for (size_t k = 0; k < plan.kept.size(); ++k) {
    const uint32_t v = plan.kept[k];
    out.positions[vertex_base + k] = add(o, p.positions[v]);
    out.normals[vertex_base + k] = p.normals[v];
    out.materials[vertex_base + k] = p.materials[v];
  }
  std::vector<uint32_t>& global = plan.local;  // rewritten in place to welded indices
  for (uint32_t& l : global) {
    if (l == kUnused) continue;
    l = (l & kForeignBit) != 0 ? plan.foreign[l & ~kForeignBit].global
                               : static_cast<uint32_t>(vertex_base + l);
  }
  uint32_t* dst = out.indices.data() + index_base;
  for (uint32_t index : p.indices) *dst++ = global[index];
}

}  // namespace

ChunkMesh weld_chunk_grid(std::span<const ChunkMesh> parts, std::array<int, 3> grid_dims,
                          Vec3f origin, int threads) {
  const size_t n = parts.size();
  const Grid grid{grid_dims, origin};
  std::vector<PartPlan> plans(n);
  tbb::task_arena arena(arena_concurrency(threads));
  parallel_for_index(arena, n,
                     [&](size_t i) { find_used_face_vertices(grid, i, parts[i], plans[i]); });
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
  parallel_for_index(arena, n, [&](size_t i) { resolve_foreign(plans, vertex_base, plans[i]); });
  parallel_for_index(arena, n, [&](size_t i) {
    write_part(grid, i, parts[i], plans[i], vertex_base[i], out, index_base[i]);
  });
  return out;
}

}  // namespace vox::mesh
