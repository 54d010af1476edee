#include "server/mesh/volume_mesher.hpp"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/mesh_welder.hpp"
#include "server/world/parallel.hpp"

namespace vox::mesh {
namespace {

using world::kChunkSize;

struct Worker {
  PaddedBlock block;
  MeshScratch scratch;
  bool materials_set = false;
};

// Block samples -1..33 of the chunk at cell origin `o`, clamped to the volume's edges
// (so normals at the border use one-sided differences).
void gather_from_volume(const QuantizedVolume& v, const std::array<int, 3>& o, PaddedBlock& out) {
  const int dx = v.dims[0], dy = v.dims[1], dz = v.dims[2];
  const int x_lo = o[0] - 1, x_hi = o[0] + kChunkSize + 1;  // inclusive block range in volume x
  const int copy_lo = std::max(x_lo, 0), copy_hi = std::min(x_hi, dx - 1);
  for (int bz = -1; bz <= kChunkSize + 1; ++bz) {
    const int vz = std::clamp(o[2] + bz, 0, dz - 1);
    for (int by = -1; by <= kChunkSize + 1; ++by) {
      const int vy = std::clamp(o[1] + by, 0, dy - 1);
      const world::Density* src =
          v.density.data() + static_cast<size_t>(dx) * (vy + static_cast<size_t>(dy) * vz);
      world::Density* dst = out.density.get() + PaddedBlock::index(-1, by, bz);
      int b = 0;
      for (int x = x_lo; x < copy_lo; ++x) dst[b++] = src[0];
      std::memcpy(dst + b, src + copy_lo, (copy_hi - copy_lo + 1) * sizeof(world::Density));
      b += copy_hi - copy_lo + 1;
      for (int x = copy_hi + 1; x <= x_hi; ++x) dst[b++] = src[dx - 1];
    }
  }
}

}  // namespace

QuantizedVolume quantize_volume(const Volume& volume, const VolumeMeshOptions& options) {
  QuantizedVolume q;
  q.dims = volume.dims;
  float scale = 0.0f;
  for (float v : volume.values) scale = std::max(scale, std::fabs(v - options.iso));
  const float sign = options.invert ? -1.0f : 1.0f;
  const float inv = scale > 0.0f ? sign / scale : 0.0f;
  q.density.resize(volume.values.size());
  for (size_t i = 0; i < volume.values.size(); ++i) {
    q.density[i] = world::quantize_density((volume.values[i] - options.iso) * inv);
  }
  return q;
}

ChunkMesh mesh_volume(const QuantizedVolume& volume, int threads) {
  std::array<int, 3> chunks{};
  for (int a = 0; a < 3; ++a)
    chunks[a] = std::max(0, (volume.dims[a] - 1 + kChunkSize - 1) / kChunkSize);
  const size_t chunk_count = static_cast<size_t>(chunks[0]) * chunks[1] * chunks[2];
  std::vector<ChunkMesh> parts(chunk_count);

  tbb::enumerable_thread_specific<std::unique_ptr<Worker>> workers(
      [] { return std::make_unique<Worker>(); });
  tbb::task_arena arena(arena_concurrency(threads));
  parallel_for_index(arena, chunk_count, [&](size_t i) {
    Worker& w = *workers.local();
    if (!w.materials_set) {
      std::fill_n(w.block.material.get(), kBlockVolume, world::Material{1});
      w.materials_set = true;
    }
    const int cx = static_cast<int>(i % chunks[0]);
    const int cy = static_cast<int>(i / chunks[0] % chunks[1]);
    const int cz = static_cast<int>(i / chunks[0] / chunks[1]);
    const std::array<int, 3> origin{cx * kChunkSize, cy * kChunkSize, cz * kChunkSize};
    for (int a = 0; a < 3; ++a)
      w.block.cells[a] = std::min(kChunkSize, volume.dims[a] - 1 - origin[a]);
    gather_from_volume(volume, origin, w.block);
    mesh_chunk(w.block, w.scratch, parts[i]);
  });
  return weld_chunk_grid(parts, chunks, Vec3f{}, threads);
}

}  // namespace vox::mesh
