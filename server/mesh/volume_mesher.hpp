// Offline meshing of a whole sampled volume (CT/MRI scans, the seed's text volumes,
// generated fields): split into 32^3-cell chunks, mesh them in parallel with TBB, weld the
// vertices the chunks share on their faces into one indexed mesh.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "server/mesh/chunk_mesh.hpp"
#include "server/world/sample.hpp"

namespace vox::mesh {

// Samples on a regular grid, x fastest, then y, then z.
struct Volume {
  std::array<int, 3> dims{};
  std::vector<float> values;
};

// Densities quantised for the mesher (see world/sample.hpp).
struct QuantizedVolume {
  std::array<int, 3> dims{};
  std::vector<world::Density> density;
};

struct VolumeMeshOptions {
  float iso = 0.0f;     // surface level
  bool invert = false;  // false: solid where value > iso (scans); true: solid where value < iso
  int threads = 0;      // 0: all cores
};

// density = (value - iso) / max|value - iso| (negated with invert), so the quantisation
// step is 1/32767 of the volume's largest distance from the iso level. Edge positions are
// ratios of densities, so the scale itself does not move the surface.
QuantizedVolume quantize_volume(const Volume& volume, const VolumeMeshOptions& options);

// Positions are in sample units, sample (0,0,0) at the origin. Vertices shared by
// neighbouring chunks appear once. `threads` 0 uses all cores.
ChunkMesh mesh_volume(const QuantizedVolume& volume, int threads = 0);

}  // namespace vox::mesh
