// Terrain that no longer holds (issue 42, "Collapse"): after an edit emptied some samples,
// the solid pieces it cut loose near them, and how far each falls before it rests.
//
// A piece is a set of solid samples (density > 0) joined through their six face
// neighbours. Within a search box around the edit, a piece holds when it reaches the box's
// faces (the world beyond the box is taken to hold it: the search never looks further) or
// the ground depth; otherwise it is detached. Only pieces the edit cut loose count: those
// touching a sample it emptied that held before it (its emptied samples counted as the
// solid they were). A piece that floated already (an island stamped in the air, even one
// dug into) is not the edit's doing and stays. Deterministic (integer arithmetic, a fixed visiting
// order), so a replay finds the same pieces. Pure; any thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "server/world/edit.hpp"
#include "server/world/material_volume.hpp"

namespace vox::world {

struct CollapseLimits {
  int32_t margin = 12;          // voxels searched around the edit's box
  int32_t max_side = 80;        // the search box's side at most, per axis
  size_t max_piece = 1 << 16;   // samples of a detached piece at most (a larger one holds)
  int32_t max_fall = 256;       // voxels a piece falls at most; further, it is removed
  int32_t ground_y = -1 << 12;  // samples at or below this height always hold
};

struct DetachedPiece {
  VoxelBox box;                            // its samples' bounds
  std::vector<std::array<int32_t, 3>> at;  // its samples, in visiting order
  int32_t fall = 0;                        // voxels down until it rests on solid ground
  bool removed = false;                    // nothing to rest on within max_fall
  // What it holds of each material, in voxels (occupancy, as an edit's yield counts it).
  std::vector<std::pair<Material, double>> holds;
};

using SampleAt = std::function<Sample(int32_t x, int32_t y, int32_t z)>;

// The box searched around an edit that changed `edit_box`: its margin added, cut to
// max_side per axis around the edit's centre.
VoxelBox collapse_search_box(const VoxelBox& edit_box, const CollapseLimits& limits);

// The pieces detached within `search` next to the `emptied` samples (those the edit turned
// from solid to air), each with its fall (read below the box through `read` as far as
// max_fall). `read` gives the world as the edit left it.
std::vector<DetachedPiece> find_detached(const SampleAt& read, const VoxelBox& search,
                                         const std::vector<std::array<int32_t, 3>>& emptied,
                                         const CollapseLimits& limits);

}  // namespace vox::world
