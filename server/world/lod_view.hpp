// One client's level-of-detail view: its layout as the eye moves, and what to
// send and unload against what the client holds. Pure bookkeeping: no I/O, no clock.
//
// Rules (each has a unit test in tests/lod_view_test.cpp):
// - The client holds, per chunk of its layout, the mesh of the seams it had when sent. A
//   chunk enters `send` when it is new to the client or its seams changed (its finer
//   neighbours came or went); `unload` lists what the layout no longer uses.
// - `send` is ordered nearest first (distance from the eye to the chunk's box), finer
//   first between equals; after update() the client holds exactly the layout.
// - The layout's hysteresis (lod_layout.hpp) keeps a player moving back and forth across a
//   boundary from reloading anything.
// One instance per client; one thread at a time.
#pragma once

#include <array>
#include <vector>

#include "server/world/lod_layout.hpp"

namespace vox::world {

struct LodViewChange {
  std::vector<std::pair<LodChunk, LodSeams>> send;
  std::vector<LodChunk> unload;
  bool empty() const { return send.empty() && unload.empty(); }
};

class LodView {
 public:
  explicit LodView(LodSettings settings) : layout_(settings) {}

  // Lays the view out around `eye` (voxels; throws std::invalid_argument as LodLayout) and
  // returns the changes, which the client is then taken to hold.
  LodViewChange update(const std::array<double, 3>& eye);
  const LodSeamsMap& held() const { return held_; }
  const LodLayout& layout() const { return layout_; }

 private:
  LodLayout layout_;
  LodSeamsMap held_;
};

}  // namespace vox::world
