#include "server/world/lod_layout.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace vox::world {
namespace {

constexpr std::array<std::array<int, 3>, 6> kFaceDirection = {
    {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}}};

LodChunk child(const LodChunk& c, int i) {
  return {c.level - 1, {2 * c.c.x + (i & 1), 2 * c.c.y + ((i >> 1) & 1), 2 * c.c.z + (i >> 2)}};
}

LodChunk neighbour(const LodChunk& c, const std::array<int, 3>& d) {
  return {c.level, c.c.offset(d[0], d[1], d[2])};
}

// The face and edge neighbours of a chunk: offsets to the chunks sharing a face or an edge.
constexpr std::array<std::array<int, 3>, 18> kNeighbourDirections = [] {
  std::array<std::array<int, 3>, 18> d{};
  for (int f = 0; f < 6; ++f) d[f] = kFaceDirection[f];
  for (int e = 0; e < kChunkEdges; ++e) d[6 + e] = lod_edge_direction(e);
  return d;
}();

// Whether the region of `n` (same level as the leaf asking, at offset `d` from it) holds
// leaves two or more levels finer than the asker: n is split and one of its children that
// touch the asker is split too.
bool has_finer_than_one_level(const LodChunk& n, const std::array<int, 3>& d,
                              const LodChunkSet& split) {
  if (n.level < 2 || !split.contains(n)) return false;
  for (int i = 0; i < 8; ++i) {
    const int bits[3] = {i & 1, (i >> 1) & 1, i >> 2};
    bool touches = true;
    for (int a = 0; a < 3; ++a) {
      if (d[a] > 0) touches &= bits[a] == 0;  // n lies above the asker on this axis
      if (d[a] < 0) touches &= bits[a] == 1;
    }
    if (touches && split.contains(child(n, i))) return true;
  }
  return false;
}

LodChunk parent(const LodChunk& c) {
  return {c.level + 1, {floor_div(c.c.x, 2), floor_div(c.c.y, 2), floor_div(c.c.z, 2)}};
}

// The index in kNeighbourDirections of the opposite direction.
constexpr std::array<int, 18> kOpposite = [] {
  std::array<int, 18> o{};
  for (int i = 0; i < 18; ++i)
    for (int j = 0; j < 18; ++j)
      if (kNeighbourDirections[j][0] == -kNeighbourDirections[i][0] &&
          kNeighbourDirections[j][1] == -kNeighbourDirections[i][1] &&
          kNeighbourDirections[j][2] == -kNeighbourDirections[i][2])
        o[i] = j;
  return o;
}();

}  // namespace

double distance_to(const LodChunk& c, const std::array<double, 3>& eye) {
  const auto lo = c.lo();
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double l = static_cast<double>(lo[a]), h = l + static_cast<double>(c.side());
    const double d = eye[a] < l ? l - eye[a] : eye[a] > h ? eye[a] - h : 0.0;
    d2 += d * d;
  }
  return std::sqrt(d2);
}

LodLayout::LodLayout(LodSettings settings) : settings_(settings) {
  if (settings_.levels < 1 || settings_.levels > 20 || settings_.top_radius < 0 ||
      settings_.top_radius > 64 || !(settings_.split_distance > 0) ||
      !(settings_.near_split_distance >= 0) || !(settings_.hysteresis >= 0)) {
    throw std::invalid_argument("LodSettings out of range");
  }
}

void LodLayout::refine(const LodChunk& node, const std::array<double, 3>& eye,
                       const LodChunkSet& was_split, LodChunkSet& leaves, LodChunkSet& split,
                       double& margin) const {
  const double band = was_split.contains(node) ? 1.0 + settings_.hysteresis : 1.0;
  const double factor = node.level == 1 && settings_.near_split_distance > 0
                            ? settings_.near_split_distance
                            : settings_.split_distance;
  const double limit = factor * band * static_cast<double>(node.side());
  if (node.level == 0) {
    leaves.insert(node);
    return;
  }
  const double distance = distance_to(node, eye);
  margin = std::min(margin, std::abs(distance - limit));
  if (distance >= limit) {
    leaves.insert(node);
    return;
  }
  split.insert(node);
  for (int i = 0; i < 8; ++i) refine(child(node, i), eye, was_split, leaves, split, margin);
}

void LodLayout::balance(LodChunkSet& leaves, LodChunkSet& split) {
  // A leaf may not touch (across a face or an edge) a leaf two or more levels finer: that
  // is, a split node of level j may not touch a leaf of level j + 1 or coarser. Every pair
  // is looked at when the later of the two appears. A split node m looks for the leaves
  // of level j + 1 touching it: the parents of its face and edge neighbours (a coarser
  // leaf touching m touches m's parent too, looked at in its turn). A new leaf c (a child
  // of a leaf just split) looks for split nodes one level finer touching it: children of
  // its same-level neighbours. Splitting a leaf makes it a split node and makes leaves.
  std::vector<LodChunk> nodes(split.begin(), split.end()), fresh;
  const auto split_leaf = [&](LodChunkSet::iterator leaf) {
    const LodChunk p = *leaf;
    leaves.erase(leaf);
    split.insert(p);
    nodes.push_back(p);
    for (int i = 0; i < 8; ++i) {
      leaves.insert(child(p, i));
      fresh.push_back(child(p, i));
    }
  };
  while (!nodes.empty() || !fresh.empty()) {
    if (!nodes.empty()) {
      const LodChunk m = nodes.back();
      nodes.pop_back();
      for (const auto& d : kNeighbourDirections) {
        const auto leaf = leaves.find(parent(neighbour(m, d)));
        if (leaf != leaves.end()) split_leaf(leaf);  // else split, coarser, or outside
      }
      continue;
    }
    const LodChunk c = fresh.back();
    fresh.pop_back();
    const auto leaf = leaves.find(c);
    if (leaf == leaves.end()) continue;  // split since
    for (const auto& d : kNeighbourDirections) {
      if (has_finer_than_one_level(neighbour(c, d), d, split)) {
        split_leaf(leaf);
        break;
      }
    }
  }
}

void LodLayout::find_seams() {
  // Leaf c has a seam towards direction d when its same-level neighbour there is split:
  // found from the split nodes, far fewer than the leaves.
  seams_.clear();
  seams_.reserve(leaves_.size());
  for (const LodChunk& c : leaves_) seams_.emplace(c, LodSeams{});
  for (const LodChunk& m : split_) {
    for (int i = 0; i < 18; ++i) {
      const auto it = seams_.find(neighbour(m, kNeighbourDirections[i]));
      if (it == seams_.end()) continue;
      const int towards = kOpposite[i];  // from the leaf to m
      if (towards < 6)
        it->second.faces = static_cast<uint8_t>(it->second.faces | (1u << towards));
      else
        it->second.edges = static_cast<uint16_t>(it->second.edges | (1u << (towards - 6)));
    }
  }
  for (auto& [c, s] : seams_) s = normalized(s);
}

bool LodLayout::update(const std::array<double, 3>& eye) {
  for (const double v : eye) {
    if (!(std::abs(v) < 1e9)) throw std::invalid_argument("LodLayout: eye outside the world");
  }
  if (settled_margin_ > 0) {  // the last layout was settled: is the eye still within it?
    double d2 = 0;
    for (int a = 0; a < 3; ++a) d2 += (eye[a] - settled_eye_[a]) * (eye[a] - settled_eye_[a]);
    if (std::sqrt(d2) < settled_margin_) return false;
  }
  const int top = settings_.levels - 1;
  const double side = static_cast<double>(int64_t{kChunkSize} << top);
  std::array<int32_t, 3> centre{};
  double margin = INFINITY;  // how far the eye may move before a decision below changes
  for (int a = 0; a < 3; ++a) {
    centre[a] = static_cast<int32_t>(std::floor(eye[a] / side));
    margin = std::min({margin, eye[a] - centre[a] * side, (centre[a] + 1) * side - eye[a]});
  }
  LodChunkSet leaves, split;
  leaves.reserve(leaves_.size());
  split.reserve(split_.size());
  const int r = settings_.top_radius;
  for (int z = -r; z <= r; ++z)
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x)
        refine({top, {centre[0] + x, centre[1] + y, centre[2] + z}}, eye, split_, leaves, split,
               margin);
  balance(leaves, split);
  const bool changed = leaves != leaves_;
  // Unchanged, the layout is settled: it was worked out from the inner nodes it has, so
  // while the eye stays within `margin` of here every decision, and so the layout, stays
  // the same (a distance to a box moves no more than the eye does).
  settled_margin_ = changed ? 0.0 : margin;
  settled_eye_ = eye;
  leaves_ = std::move(leaves);
  split_ = std::move(split);
  if (changed || seams_.size() != leaves_.size()) find_seams();
  return changed;
}

LodSeams LodLayout::seams(const LodChunk& c) const {
  const auto it = seams_.find(c);
  return it == seams_.end() ? LodSeams{} : it->second;
}

}  // namespace vox::world
