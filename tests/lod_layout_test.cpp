// The level-of-detail layout (server/world/lod_layout.hpp): rings without gap or overlap,
// the 2:1 rule between face neighbours, hysteresis, and the faces that get transitions.
#include "server/world/lod_layout.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <vector>

namespace vox::world {
namespace {

// The leaf holding voxel point p (each leaf a half-open box), and how many hold it.
std::pair<const LodChunk*, int> leaf_at(const LodLayout& layout, const std::array<int64_t, 3>& p) {
  const LodChunk* found = nullptr;
  int count = 0;
  for (const LodChunk& c : layout.chunks()) {
    const auto lo = c.lo();
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside &= p[a] >= lo[a] && p[a] < lo[a] + c.side();
    if (inside) {
      found = &c;
      ++count;
    }
  }
  return {found, count};
}

TEST(LodLayout, LeavesCoverTheTopRegionOnceWithoutGapOrOverlap) {
  LodLayout layout({.levels = 5, .top_radius = 1});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-900.0, 900.0);
  for (int trial = 0; trial < 10; ++trial) {
    const std::array<double, 3> eye{pos(rng), pos(rng) * 0.2, pos(rng)};
    layout.update(eye);
    // Volumes add up to the 3x3x3 top chunks...
    const int64_t top = int64_t{32} << 4;
    int64_t volume = 0;
    for (const LodChunk& c : layout.chunks()) volume += c.side() * c.side() * c.side();
    EXPECT_EQ(volume, 27 * top * top * top);
    // ... and every sampled point is in exactly one leaf: no gap, so no overlap either.
    std::uniform_int_distribution<int64_t> off(0, 3 * top - 1);
    std::array<int64_t, 3> base{};
    for (int a = 0; a < 3; ++a)
      base[a] = (static_cast<int64_t>(std::floor(eye[a] / static_cast<double>(top))) - 1) * top;
    for (int k = 0; k < 300; ++k) {
      const std::array<int64_t, 3> p{base[0] + off(rng), base[1] + off(rng), base[2] + off(rng)};
      EXPECT_EQ(leaf_at(layout, p).second, 1);
    }
    // Level 0 where the eye is; coarser farther away.
    const auto [at_eye, n] = leaf_at(
        layout, {static_cast<int64_t>(std::floor(eye[0])), static_cast<int64_t>(std::floor(eye[1])),
                 static_cast<int64_t>(std::floor(eye[2]))});
    ASSERT_EQ(n, 1);
    EXPECT_EQ(at_eye->level, 0);
  }
}

TEST(LodLayout, FaceAndEdgeNeighboursDifferByAtMostOneLevelAndFinerOnesAreSeams) {
  for (double split : {1.0, 1.5, 2.0}) {
    LodLayout layout({.levels = 6, .top_radius = 1, .split_distance = split});
    layout.update({100.3, 7.7, -40.2});
    int finer_faces = 0, finer_edges_only = 0;
    for (const LodChunk& c : layout.chunks()) {
      const auto lo = c.lo();
      const int64_t s = c.side();
      const LodSeams seams = layout.seams(c);
      // The point just across the middle of each face and of each edge.
      auto across = [&](const std::array<int, 3>& d) {
        std::array<int64_t, 3> p{};
        for (int a = 0; a < 3; ++a)
          p[a] = d[a] < 0 ? lo[a] - 1 : d[a] > 0 ? lo[a] + s : lo[a] + s / 2;
        return leaf_at(layout, p);
      };
      for (int f = 0; f < 6; ++f) {
        std::array<int, 3> d{};
        d[f / 2] = f % 2 == 0 ? -1 : 1;
        const auto [n, count] = across(d);
        if (count == 0) continue;  // outside the layout
        EXPECT_LE(std::abs(n->level - c.level), 1) << "split " << split;
        EXPECT_EQ((seams.faces >> f) & 1, n->level < c.level ? 1 : 0);
        finer_faces += n->level < c.level;
      }
      for (int e = 0; e < kChunkEdges; ++e) {
        const auto [n, count] = across(lod_edge_direction(e));
        if (count == 0) continue;
        EXPECT_LE(std::abs(n->level - c.level), 1) << "split " << split;
        const bool from_faces = (normalized({seams.faces, 0}).edges >> e) & 1;
        EXPECT_EQ((seams.edges >> e) & 1, n->level < c.level || from_faces ? 1 : 0);
        finer_edges_only += n->level < c.level && !from_faces;
      }
      EXPECT_EQ(normalized(seams), seams);
    }
    EXPECT_GT(finer_faces, 0);
    EXPECT_GT(finer_edges_only, 0) << "a chunk touched by a finer one only across an edge";
  }
}

TEST(LodLayout, MovingBackAndForthAcrossABoundaryDoesNotReload) {
  LodLayout layout({.levels = 4, .top_radius = 1, .split_distance = 2.0, .hysteresis = 0.25});
  // Walk along x until the layout changes: a split boundary has been crossed.
  std::array<double, 3> eye{10.5, 10.5, 10.5};
  layout.update(eye);
  double x = eye[0];
  for (int step = 0; step < 2000 && !layout.update({x, eye[1], eye[2]}); ++step) x += 1.0;
  const auto after = layout.chunks();
  // One voxel back and forth, many times: nothing changes.
  for (int i = 0; i < 20; ++i) {
    EXPECT_FALSE(layout.update({x - 1.0, eye[1], eye[2]})) << i;
    EXPECT_FALSE(layout.update({x, eye[1], eye[2]})) << i;
  }
  EXPECT_EQ(layout.chunks(), after);
  // Without hysteresis the same walk flickers.
  LodLayout flicker({.levels = 4, .top_radius = 1, .split_distance = 2.0, .hysteresis = 0.0});
  flicker.update({x, eye[1], eye[2]});
  bool changed = false;
  for (double d = 0.25; d <= 1.0 && !changed; d += 0.25) {
    changed |= flicker.update({x - d, eye[1], eye[2]});
    changed |= flicker.update({x, eye[1], eye[2]});
  }
  EXPECT_TRUE(changed);
}

// A walking player's SetViews mostly leave the layout as it was, and a settled layout
// skips the work while the eye stays within the margin it computed: along a random walk
// it is always the layout worked out in full.
TEST(LodLayout, ASettledLayoutIsTheLayoutWorkedOutInFullAlongAWalk) {
  const LodSettings settings{
      .levels = 5, .top_radius = 1, .split_distance = 2.0, .near_split_distance = 2.0};
  LodLayout quick(settings), full(settings);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> step(-3.0, 3.0);
  std::array<double, 3> eye{-300.25, 40.5, 900.75};
  int settled = 0;
  for (int i = 0; i < 1000; ++i) {
    for (double& v : eye) v += step(rng) * (i % 100 == 0 ? 40.0 : 1.0);  // now and then a jump
    settled += quick.settled() ? 1 : 0;
    const bool changed = quick.update(eye);
    full.forget_settled();
    EXPECT_EQ(changed, full.update(eye)) << i;
    ASSERT_EQ(quick.chunks(), full.chunks()) << "step " << i;
  }
  EXPECT_GT(settled, 400) << "most steps are skipped";
}

// The layout of a first update, worked out the plain way (the first implementation): each
// node split while the eye is nearer than its split distance; then, leaf by leaf, a leaf
// split when a same-level face or edge neighbour is split and that neighbour's child
// touching the leaf is split too, until no leaf is.
LodChunkSet plain_layout(const LodSettings& s, const std::array<double, 3>& eye, size_t& balanced) {
  LodChunkSet leaves, split;
  const auto child = [](const LodChunk& c, int i) {
    return LodChunk{c.level - 1,
                    {2 * c.c.x + (i & 1), 2 * c.c.y + ((i >> 1) & 1), 2 * c.c.z + (i >> 2)}};
  };
  std::vector<LodChunk> work;
  const int top = s.levels - 1;
  const double side = static_cast<double>(int64_t{kChunkSize} << top);
  for (int z = -s.top_radius; z <= s.top_radius; ++z)
    for (int y = -s.top_radius; y <= s.top_radius; ++y)
      for (int x = -s.top_radius; x <= s.top_radius; ++x)
        work.push_back({top,
                        {static_cast<int32_t>(std::floor(eye[0] / side)) + x,
                         static_cast<int32_t>(std::floor(eye[1] / side)) + y,
                         static_cast<int32_t>(std::floor(eye[2] / side)) + z}});
  while (!work.empty()) {
    const LodChunk c = work.back();
    work.pop_back();
    const double factor =
        c.level == 1 && s.near_split_distance > 0 ? s.near_split_distance : s.split_distance;
    if (c.level == 0 || distance_to(c, eye) >= factor * static_cast<double>(c.side())) {
      leaves.insert(c);
      continue;
    }
    split.insert(c);
    for (int i = 0; i < 8; ++i) work.push_back(child(c, i));
  }
  std::vector<std::array<int, 3>> directions = {{-1, 0, 0}, {1, 0, 0},  {0, -1, 0},
                                                {0, 1, 0},  {0, 0, -1}, {0, 0, 1}};
  for (int e = 0; e < kChunkEdges; ++e) directions.push_back(lod_edge_direction(e));
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<LodChunk> to_split;
    for (const LodChunk& leaf : leaves) {
      for (const auto& d : directions) {
        const LodChunk n{leaf.level, leaf.c.offset(d[0], d[1], d[2])};
        if (n.level < 2 || !split.contains(n)) continue;
        bool finer = false;
        for (int i = 0; i < 8; ++i) {
          const int bits[3] = {i & 1, (i >> 1) & 1, i >> 2};
          bool touches = true;
          for (int a = 0; a < 3; ++a)
            touches &= d[a] > 0 ? bits[a] == 0 : d[a] < 0 ? bits[a] == 1 : true;
          finer |= touches && split.contains(child(n, i));
        }
        if (finer) {
          to_split.push_back(leaf);
          break;
        }
      }
    }
    balanced += to_split.size();
    for (const LodChunk& leaf : to_split) {
      leaves.erase(leaf);
      split.insert(leaf);
      for (int i = 0; i < 8; ++i) leaves.insert(child(leaf, i));
      changed = true;
    }
  }
  return leaves;
}

// Balancing works from the split nodes (far fewer than the leaves, and a walking player's
// layout is laid out again every few voxels): the same layout as the plain way.
TEST(LodLayout, TheBalancedLayoutIsThePlainOneWhereverTheEye) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> coord(-5000.0, 5000.0);
  size_t balanced = 0;  // leaves the plain way split for the 2:1 rule
  for (const LodSettings& s :
       {LodSettings{.levels = 5, .top_radius = 1, .split_distance = 1.0},
        LodSettings{
            .levels = 7, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0},
        LodSettings{.levels = 6, .top_radius = 2, .split_distance = 1.5},
        // Short split distances leave room for a split to create leaves next to finer
        // split nodes already looked at (found in review).
        LodSettings{.levels = 5, .top_radius = 1, .split_distance = 0.25},
        LodSettings{.levels = 6, .top_radius = 1, .split_distance = 0.4}}) {
    for (int i = 0; i < 40; ++i) {
      const std::array<double, 3> eye =
          i == 0 ? std::array<double, 3>{200, 200, 200}  // the review's case
                 : std::array<double, 3>{coord(rng), coord(rng) * 0.1, coord(rng)};
      LodLayout layout(s);
      layout.update(eye);
      ASSERT_EQ(layout.chunks(), plain_layout(s, eye, balanced))
          << "levels " << s.levels << " eye " << i;
    }
  }
  EXPECT_GT(balanced, 0u);
}

TEST(LodLayout, FarFromTheEyeTheChunksAreCoarse) {
  LodLayout layout({.levels = 7, .top_radius = 1, .split_distance = 2.0});
  layout.update({0.5, 0.5, 0.5});
  std::map<int, int> per_level;
  for (const LodChunk& c : layout.chunks()) ++per_level[c.level];
  // Level 0 covers about 2 level-1 sides (128 voxels) around the eye, not the whole view.
  EXPECT_GT(per_level[0], 0);
  EXPECT_LT(per_level[0], 1000);
  // The top level's chunks all lie within split_distance of the eye: split, so the
  // coarsest leaves are one level below (1024 voxels on a side, out to 3072 voxels).
  EXPECT_EQ(per_level[6], 0);
  EXPECT_GT(per_level[5], 0);
  EXPECT_THROW(LodLayout({.levels = 0}), std::invalid_argument);
}

// near_split_distance sets how far level 0 reaches: every voxel within that many level-1
// sides (64 voxels) of the eye is level 0, whatever split_distance says for the others.
TEST(LodLayout, LevelZeroReachesTheNearSplitDistanceWhateverTheCoarserOnes) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(-500.0, 500.0), dir(-1.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    const std::array<double, 3> eye{pos(rng), pos(rng) * 0.1, pos(rng)};
    LodLayout near({.levels = 7, .split_distance = 1.0, .near_split_distance = 2.0});
    LodLayout plain({.levels = 7, .split_distance = 1.0});
    near.update(eye);
    plain.update(eye);
    for (int k = 0; k < 200; ++k) {
      std::array<double, 3> d{dir(rng), dir(rng), dir(rng)};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      std::array<int64_t, 3> p{};
      for (int a = 0; a < 3; ++a)
        p[a] = static_cast<int64_t>(std::floor(eye[a] + d[a] / len * 127.0));
      const auto [leaf, count] = leaf_at(near, p);
      ASSERT_EQ(count, 1);
      EXPECT_EQ(leaf->level, 0) << "127 voxels from the eye";
    }
    std::map<int, int> a, b;
    for (const LodChunk& c : near.chunks()) ++a[c.level];
    for (const LodChunk& c : plain.chunks()) ++b[c.level];
    EXPECT_GT(a[0], b[0]);
  }
}

}  // namespace
}  // namespace vox::world
