// Which chunk of which level covers each region around a player (level of detail, issue
// 16). A level-k chunk has 32^3 cells over 32 * 2^k voxels per side; level-k chunk c covers
// voxels [32 * 2^k * c, 32 * 2^k * (c + 1)). The layout is the leaves of an octree: the
// level-L chunks around the eye, each split into its 8 level-(k-1) children while the eye
// is closer to it than split_distance times its side, recursively. So leaves never overlap
// and leave no gap. Chunks sharing a face or an edge differ by at most one level (the 2:1
// rule the seams of lod_seams.hpp need): a leaf with such a neighbour two levels finer is
// split too. A chunk split in the previous layout merges back only when the eye is farther
// than (1 + hysteresis) times that distance, so moving back and forth across a boundary
// does not reload.
//
// A pure policy: no I/O, no clock. One instance per client; one thread at a time.
#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>

#include "server/world/chunk_coord.hpp"
#include "server/world/lod_seams.hpp"

namespace vox::world {

struct LodChunk {
  int level = 0;
  ChunkCoord c;  // in level-`level` chunks
  friend constexpr auto operator<=>(const LodChunk&, const LodChunk&) = default;

  int64_t side() const { return int64_t{kChunkSize} << level; }  // in voxels
  std::array<int64_t, 3> lo() const { return {c.x * side(), c.y * side(), c.z * side()}; }
};

struct LodChunkHash {
  size_t operator()(const LodChunk& c) const {
    return ChunkCoordHash{}(c.c) ^ (static_cast<size_t>(c.level) * 0x9E3779B97F4A7C15ull);
  }
};
// Chunks of a layout: hashed (a layout is rebuilt on every SetView of a walking player,
// and an ordered tree's lookups were 7 % of a loaded server's CPU).
using LodChunkSet = std::unordered_set<LodChunk, LodChunkHash>;
using LodSeamsMap = std::unordered_map<LodChunk, LodSeams, LodChunkHash>;

// Distance from `eye` (voxels) to the chunk's box, 0 inside.
double distance_to(const LodChunk& c, const std::array<double, 3>& eye);

struct LodSettings {
  int levels = 7;               // level 0 .. levels-1; the top level's chunks are laid out first
  int top_radius = 1;           // top-level chunks within this many of the eye's, per axis
  double split_distance = 2.0;  // in sides of the chunk: closer than this, it is split
  // The same for level-1 chunks (how far level 0 reaches); 0: split_distance.
  double near_split_distance = 0.0;
  double hysteresis = 0.25;  // a split chunk merges beyond (1 + this) * split_distance
};

// Faces of a chunk, the bit of each in LodSeams::faces.
enum LodFace : uint8_t {
  kMinusX = 1,
  kPlusX = 2,
  kMinusY = 4,
  kPlusY = 8,
  kMinusZ = 16,
  kPlusZ = 32
};

class LodLayout {
 public:
  explicit LodLayout(LodSettings settings);

  // Lays the chunks out around `eye` (voxel coordinates; throws std::invalid_argument
  // when not finite or beyond 1e9); returns whether the layout changed.
  bool update(const std::array<double, 3>& eye);
  const LodChunkSet& chunks() const { return leaves_; }
  // Where leaf `c` meets finer leaves (lod_seams.hpp); none for a chunk that is not in
  // the layout.
  LodSeams seams(const LodChunk& c) const;
  const LodSeamsMap& all_seams() const { return seams_; }  // every leaf's
  const LodSettings& settings() const { return settings_; }
  // Whether the last update() found the layout unchanged and settled it: then updates
  // within a margin of that eye (the nearest split decision or top-level boundary)
  // return false at once. forget_settled() makes the next update work it out in full.
  bool settled() const { return settled_margin_ > 0; }
  void forget_settled() { settled_margin_ = 0; }

 private:
  void refine(const LodChunk& node, const std::array<double, 3>& eye, const LodChunkSet& was_split,
              LodChunkSet& leaves, LodChunkSet& split, double& margin) const;
  // Splits leaves that have a face or edge neighbour two or more levels finer, until none
  // has.
  static void balance(LodChunkSet& leaves, LodChunkSet& split);
  void find_seams();  // seams_ of leaves_ and split_

  LodSettings settings_;
  LodChunkSet leaves_;
  LodChunkSet split_;  // the inner nodes of the octree
  LodSeamsMap seams_;  // of every leaf
  // When the last update left the layout unchanged: the eye then, and how far it may move
  // from there before any split decision changes (0: not settled).
  std::array<double, 3> settled_eye_{};
  double settled_margin_ = 0;
};

}  // namespace vox::world
