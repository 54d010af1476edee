#include "server/world/collapse.hpp"

#include <algorithm>
#include <deque>

namespace vox::world {

namespace {

constexpr int kNeighbour[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                  {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

// The search box's samples: solid or not, a label per sample (0: not visited; 1: holds;
// 2 + k: piece k), and the material.
struct Grid {
  VoxelBox box;
  int32_t n[3];
  std::vector<uint8_t> solid;
  std::vector<Material> material;
  std::vector<uint32_t> label;
  size_t index(int32_t x, int32_t y, int32_t z) const {
    return static_cast<size_t>(x - box.lo[0]) +
           static_cast<size_t>(n[0]) *
               (static_cast<size_t>(y - box.lo[1]) +
                static_cast<size_t>(n[1]) * static_cast<size_t>(z - box.lo[2]));
  }
  bool inside(int32_t x, int32_t y, int32_t z) const {
    return x >= box.lo[0] && x <= box.hi[0] && y >= box.lo[1] && y <= box.hi[1] && z >= box.lo[2] &&
           z <= box.hi[2];
  }
  bool on_face(int32_t x, int32_t y, int32_t z) const {
    return x == box.lo[0] || x == box.hi[0] || y == box.lo[1] || y == box.hi[1] || z == box.lo[2] ||
           z == box.hi[2];
  }
};

constexpr uint32_t kHolds = 1;

// Whether the samples joined to `start` reached a face or the ground before the edit: the
// samples it emptied (`was_solid`) counted as the solid they were. Reads the grid only.
bool held_before(const Grid& g, const std::vector<uint8_t>& was_solid, std::array<int32_t, 3> start,
                 int32_t ground_y) {
  std::vector<uint8_t> seen(g.solid.size(), 0);
  std::deque<std::array<int32_t, 3>> todo{start};
  seen[g.index(start[0], start[1], start[2])] = 1;
  while (!todo.empty()) {
    const auto p = todo.front();
    todo.pop_front();
    if (g.on_face(p[0], p[1], p[2]) || p[1] <= ground_y) return true;
    for (const auto& d : kNeighbour) {
      const size_t i = g.index(p[0] + d[0], p[1] + d[1], p[2] + d[2]);
      if (seen[i] || !(g.solid[i] || was_solid[i])) continue;
      seen[i] = 1;
      todo.push_back({p[0] + d[0], p[1] + d[1], p[2] + d[2]});
    }
  }
  return false;
}

// Labels every solid sample joined to `start` with `label`; stops (returning false) past
// `max` samples or on reaching a face or the ground, where `held` is set.
bool flood(Grid& g, std::array<int32_t, 3> start, uint32_t label, size_t max, int32_t ground_y,
           std::vector<std::array<int32_t, 3>>& out, bool& held) {
  std::deque<std::array<int32_t, 3>> todo{start};
  g.label[g.index(start[0], start[1], start[2])] = label;
  held = false;
  while (!todo.empty()) {
    const auto p = todo.front();
    todo.pop_front();
    out.push_back(p);
    if (g.on_face(p[0], p[1], p[2]) || p[1] <= ground_y || out.size() > max) {
      held = true;
      return false;
    }
    for (const auto& d : kNeighbour) {
      const int32_t x = p[0] + d[0], y = p[1] + d[1], z = p[2] + d[2];
      const size_t i = g.index(x, y, z);  // inside: p is not on a face
      if (!g.solid[i] || g.label[i] != 0) continue;
      g.label[i] = label;
      todo.push_back({x, y, z});
    }
  }
  return true;
}

}  // namespace

VoxelBox collapse_search_box(const VoxelBox& edit_box, const CollapseLimits& limits) {
  VoxelBox b;
  for (int a = 0; a < 3; ++a) {
    const int64_t lo = int64_t{edit_box.lo[a]} - limits.margin;
    const int64_t hi = int64_t{edit_box.hi[a]} + limits.margin;
    const int64_t mid = (int64_t{edit_box.lo[a]} + edit_box.hi[a]) / 2;
    const int64_t half = limits.max_side / 2;
    b.lo[a] = static_cast<int32_t>(std::max(lo, mid - half));
    b.hi[a] = static_cast<int32_t>(std::min(hi, mid - half + limits.max_side - 1));
  }
  return b;
}

std::vector<DetachedPiece> find_detached(const SampleAt& read, const VoxelBox& search,
                                         const std::vector<std::array<int32_t, 3>>& emptied,
                                         const CollapseLimits& limits) {
  Grid g;
  g.box = search;
  size_t total = 1;
  for (int a = 0; a < 3; ++a) {
    g.n[a] = search.hi[a] - search.lo[a] + 1;
    if (g.n[a] < 3) return {};
    total *= static_cast<size_t>(g.n[a]);
  }
  g.solid.resize(total);
  g.material.resize(total);
  g.label.assign(total, 0);
  for (int32_t z = search.lo[2]; z <= search.hi[2]; ++z)
    for (int32_t y = search.lo[1]; y <= search.hi[1]; ++y)
      for (int32_t x = search.lo[0]; x <= search.hi[0]; ++x) {
        const Sample s = read(x, y, z);
        const size_t i = g.index(x, y, z);
        g.solid[i] = is_solid(s.density) ? 1 : 0;
        g.material[i] = s.material;
      }
  std::vector<uint8_t> was_solid(total, 0);
  for (const auto& e : emptied)
    if (g.inside(e[0], e[1], e[2])) was_solid[g.index(e[0], e[1], e[2])] = 1;
  std::vector<DetachedPiece> pieces;
  std::vector<std::array<int32_t, 3>> found;
  for (const auto& e : emptied) {
    if (!g.inside(e[0], e[1], e[2])) continue;
    for (const auto& d : kNeighbour) {
      const int32_t x = e[0] + d[0], y = e[1] + d[1], z = e[2] + d[2];
      if (!g.inside(x, y, z)) continue;
      const size_t i = g.index(x, y, z);
      if (!g.solid[i] || g.label[i] != 0) continue;
      found.clear();
      bool held = false;
      const uint32_t label = 2 + static_cast<uint32_t>(pieces.size());
      if (!flood(g, {x, y, z}, label, limits.max_piece, limits.ground_y, found, held) || held) {
        // Holds: everything joined to it holds too (labelled so, never searched again).
        for (const auto& p : found) g.label[g.index(p[0], p[1], p[2])] = kHolds;
        std::deque<std::array<int32_t, 3>> todo(found.begin(), found.end());
        while (!todo.empty()) {
          const auto p = todo.front();
          todo.pop_front();
          for (const auto& dd : kNeighbour) {
            const int32_t qx = p[0] + dd[0], qy = p[1] + dd[1], qz = p[2] + dd[2];
            if (!g.inside(qx, qy, qz)) continue;
            const size_t q = g.index(qx, qy, qz);
            if (!g.solid[q] || g.label[q] == kHolds) continue;
            g.label[q] = kHolds;
            todo.push_back({qx, qy, qz});
          }
        }
        continue;
      }
      // Cut loose by this edit only if it held before: a piece that floated already (an
      // island stamped in the air, dug into) stays where it is.
      if (!held_before(g, was_solid, found.front(), limits.ground_y)) continue;
      DetachedPiece piece;
      piece.at = found;
      piece.box.lo = piece.box.hi = found.front();
      VolumeTally tally;
      for (const auto& p : found) {
        for (int a = 0; a < 3; ++a)
          piece.box.lo[a] = std::min(piece.box.lo[a], p[a]),
          piece.box.hi[a] = std::max(piece.box.hi[a], p[a]);
        const Sample s = read(p[0], p[1], p[2]);
        tally.add(s, Sample{kDensityMin, s.material});
      }
      tally.materials(
          [&](const MaterialVolume& v) { piece.holds.emplace_back(v.material, v.removed); });
      pieces.push_back(std::move(piece));
    }
  }
  // Each piece falls until one of its columns rests on a solid sample that is not its own
  // (nor another falling piece's).
  for (DetachedPiece& piece : pieces) {
    std::vector<std::array<int32_t, 3>> lowest;  // (x, lowest y, z) per column
    {
      std::vector<std::array<int32_t, 3>> by_column = piece.at;
      std::sort(by_column.begin(), by_column.end(), [](const auto& a, const auto& b) {
        return a[0] != b[0] ? a[0] < b[0] : a[2] != b[2] ? a[2] < b[2] : a[1] < b[1];
      });
      for (const auto& p : by_column)
        if (lowest.empty() || lowest.back()[0] != p[0] || lowest.back()[2] != p[2])
          lowest.push_back(p);
    }
    int32_t fall = limits.max_fall + 1;
    for (const auto& p : lowest) {
      for (int32_t d = 1; d < fall; ++d) {
        const int32_t y = p[1] - d;
        const bool in_grid = g.inside(p[0], y, p[2]);
        const bool solid =
            in_grid ? g.solid[g.index(p[0], y, p[2])] && g.label[g.index(p[0], y, p[2])] < 2
                    : is_solid(read(p[0], y, p[2]).density);
        if (solid || y <= limits.ground_y) {
          fall = d - 1;
          break;
        }
      }
    }
    piece.removed = fall > limits.max_fall;
    piece.fall = piece.removed ? 0 : fall;
  }
  return pieces;
}

}  // namespace vox::world
