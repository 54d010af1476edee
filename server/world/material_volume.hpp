// What an edit removed and added of each material, in voxels, from the density change
// (docs/PROTOCOL.md 4.4, "Material yield"). A sample's share of solid is its density mapped
// from [-1, 1] onto [0, 1] (deep rock 1, open air 0, a sample on the surface a half). A
// sample whose material changed gave up its old share of the old material and holds its new
// share of the new one; air samples have material 0, so a sample dug out gives up all it
// held, and the figures come close to, not exactly to, the volume under the drawn surface. Counted
// in density steps (exact integers, the same on every machine); material 0 (none) is not counted.
#pragma once

#include <array>
#include <cstdint>

#include "server/world/sample.hpp"

namespace vox::world {

// The steps of a whole voxel: densities kDensityMin .. kDensityMax.
inline constexpr int64_t kVoxelSteps = int64_t{kDensityMax} - kDensityMin;

struct MaterialVolume {
  Material material = kAir;
  double removed = 0, added = 0;  // voxels
};

class VolumeTally {
 public:
  void add(Sample old, Sample now) {
    const int64_t before = int64_t{old.density} - kDensityMin;
    const int64_t after = int64_t{now.density} - kDensityMin;
    if (old.material == now.material) {
      if (after > before)
        added_[now.material] += after - before;
      else
        removed_[now.material] += before - after;
    } else {
      removed_[old.material] += before;
      added_[now.material] += after;
    }
  }
  void merge(const VolumeTally& other) {
    for (size_t m = 0; m < 256; ++m) removed_[m] += other.removed_[m], added_[m] += other.added_[m];
  }
  // The materials with a change, in id order.
  template <class Out>
  void materials(Out&& out) const {
    for (size_t m = 1; m < 256; ++m)
      if (removed_[m] != 0 || added_[m] != 0)
        out(MaterialVolume{static_cast<Material>(m), static_cast<double>(removed_[m]) / kVoxelSteps,
                           static_cast<double>(added_[m]) / kVoxelSteps});
  }

 private:
  std::array<int64_t, 256> removed_{}, added_{};
};

}  // namespace vox::world
