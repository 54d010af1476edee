// Offline meshing of a whole sampled volume (CT/MRI scans, the seed's text volumes,
// generated fields): split into 32^3-cell chunks, mesh them in parallel with TBB, weld the
// vertices the chunks share on their faces into one indexed mesh.
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <span>
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
  Buffer<world::Density> density;
  // A sample exactly on the iso level (density 0) is solid: it is without --invert, so
  // that solid is value >= iso, the partition VTK's Flying Edges meshes.
  bool zero_is_solid = false;
};

struct VolumeMeshOptions {
  float iso = 0.0f;     // surface level
  bool invert = false;  // false: solid where value > iso (scans); true: solid where value < iso
  int threads = 0;      // 0: all cores
};

// A float volume as the streaming mesher reads it. `release` (may be empty) is told ranges
// of samples that will not be read again, so that the pages of a mapped file can leave
// memory; it may be called from any of the mesher's threads, for disjoint ranges.
struct FloatVolumeView {
  std::array<int, 3> dims{};
  std::span<const float> values;
  std::function<void(size_t begin, size_t end)> release;
};

// The volume's largest |value - iso|: the quantisation scale below. Runs on
// options.threads, releasing each range it has read. Throws std::domain_error("value I is
// not finite") for a NaN or an infinity.
float volume_scale(const FloatVolumeView& volume, const VolumeMeshOptions& options);

// density = (value - iso) / max|value - iso| (negated with invert), so the quantisation
// step is 1/32767 of the volume's largest distance from the iso level. Edge positions are
// ratios of densities, so the scale itself does not move the surface. The sign is kept
// exactly: a value above the level never rounds to 0, nor one below it. Runs on
// `options.threads`. Throws std::domain_error("value I is not finite") for a NaN or an
// infinity.
QuantizedVolume quantize_samples(std::array<int, 3> dims, std::span<const float> values,
                                 const VolumeMeshOptions& options);
QuantizedVolume quantize_volume(const Volume& volume, const VolumeMeshOptions& options);

// The p-th percentile (p in [0, 100]) of the values: the value at rank
// round(p / 100 * (n - 1)) in sorted order. Linear time (a histogram, then a selection
// inside one bin). Throws std::domain_error for a NaN or an infinity.
float value_percentile(std::span<const float> values, double p);

// Scales positions by `spacing` (a voxel's size per axis) and turns the normals with them
// (a normal scales by 1/spacing, then is made unit length again).
void apply_spacing(ChunkMesh& mesh, const std::array<float, 3>& spacing);

// Meshes floats without an int16 copy of the volume: each chunk's padded block is
// quantised (as quantize_samples does) while it is gathered, a z-layer of chunks at a
// time, and the samples below the next layer are released. Same mesh as
// mesh_volume(quantize_samples(...)). Throws as volume_scale.
ChunkMesh mesh_float_volume(const FloatVolumeView& volume, const VolumeMeshOptions& options);

// Positions are in sample units, sample (0,0,0) at the origin. Vertices shared by
// neighbouring chunks appear once. `threads` 0 uses all cores.
ChunkMesh mesh_volume(const QuantizedVolume& volume, int threads = 0);

}  // namespace vox::mesh
