// One voxel sample: a signed density and a material id.
//
// Representation: density is quantised to int16 as round(d * 32767) for d in [-1, 1]
// (step 1/32767 ~ 3.05e-5). Solid is density > 0, the surface is at 0. Quantisation keeps
// the sign: a positive value never rounds to 0, so solid/air never flips by rounding.
// Material 0 means "none" (air); solid materials are 1..255.
#pragma once

#include <algorithm>
#include <cstdint>

namespace vox::world {

using Density = int16_t;
using Material = uint8_t;

inline constexpr Density kDensityMax = 32767;
inline constexpr Density kDensityMin = -32767;
inline constexpr Material kAir = 0;

struct Sample {
  Density density = kDensityMin;
  Material material = kAir;
  friend constexpr bool operator==(const Sample&, const Sample&) = default;
};

// d is clamped to [-1, 1]; NaN maps to air (-1); rounds half away from zero, except that
// a positive d never gives 0 (sign-preserving, see above). Branch-free so that loops over
// many samples vectorise.
inline Density quantize_density(float d) {
  const float c = std::min(d > -1.0f ? d : -1.0f, 1.0f);  // NaN compares false: -1
  const float scaled = c * 32767.0f;
  int q = static_cast<int>(scaled + (scaled >= 0.0f ? 0.5f : -0.5f));
  q += (q == 0) & (c > 0.0f);
  return static_cast<Density>(q);
}

inline constexpr float dequantize_density(Density q) { return static_cast<float>(q) / 32767.0f; }

inline constexpr bool is_solid(Density q) { return q > 0; }

}  // namespace vox::world
