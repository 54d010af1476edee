#include "server/mesh/volume_mesher.hpp"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/mesh_welder.hpp"
#include "server/world/parallel.hpp"

namespace vox::mesh {
namespace {

using world::kChunkSize;

// The largest |value - iso| of values[begin, end) as the bits of a non-negative float:
// those order as the floats do, and an infinity or a NaN is above every finite one. An
// integer max reduction, which the compiler vectorises (a float one it would not: NaN).
uint32_t largest_distance_bits(const float* values, size_t begin, size_t end, float iso) {
  uint32_t m = 0;
  for (size_t i = begin; i < end; ++i)
    m = std::max(m, std::bit_cast<uint32_t>(values[i] - iso) & 0x7fffffffu);
  return m;
}

// How floats become densities: round(e * k) for e = (value - iso) * sign, at most 32767 in
// magnitude, but +-1 where that rounds to 0 and e is not 0.
struct Quantizer {
  float iso = 0, sign = 1, k = 0;

  // A scale below 1 is first brought into [1, 2) (at most 2^100 up) by an exact power of
  // two folded into `sign`: 32767 / scale overflowed to infinity below about 1e-34, and
  // 0 * infinity is NaN.
  Quantizer(const VolumeMeshOptions& options, float scale) : iso(options.iso) {
    const float up =
        scale > 0.0f && scale < 1.0f ? std::ldexp(1.0f, std::min(100, -std::ilogb(scale))) : 1.0f;
    sign = (options.invert ? -1.0f : 1.0f) * up;
    k = scale > 0.0f ? 32767.0f / (scale * up) : 0.0f;
  }

  // out[0, n) from values[0, n). Sign and magnitude by bits and integer selects, so that
  // it vectorises (float compares may trap, which keeps them out of vector selects); out
  // of line, so that every caller gets the vectorised loop.
  [[gnu::noinline]] void run(const float* values, size_t n, world::Density* out) const {
    for (size_t i = 0; i < n; ++i) {
      const uint32_t e = std::bit_cast<uint32_t>((values[i] - iso) * sign);
      const float magnitude = std::bit_cast<float>(e & 0x7fffffffu) * k;
      int q = static_cast<int>(magnitude + 0.5f);
      q = std::min(std::max(q, static_cast<int>((e & 0x7fffffffu) != 0)), 32767);
      const int negative = static_cast<int>(e >> 31);
      out[i] = static_cast<world::Density>((q ^ -negative) + negative);
    }
  }
};

constexpr size_t kScanBlock = size_t{1} << 20;  // samples per task of a whole-volume pass

struct Worker {
  PaddedBlock block;
  MeshScratch scratch;
  bool materials_set = false;
};

// Block samples -1..33 of the chunk at cell origin `o`, clamped to the volume's edges
// (so normals at the border use one-sided differences). copy_row(row, first, n, dst) puts
// samples [first, first + n) of volume row `row` (= y + dims[1] * z) as densities at dst.
template <class CopyRow>
void gather_block(const std::array<int, 3>& dims, const std::array<int, 3>& o, PaddedBlock& out,
                  const CopyRow& copy_row) {
  const int dx = dims[0], dy = dims[1], dz = dims[2];
  const int x_lo = o[0] - 1, x_hi = o[0] + kChunkSize + 1;  // inclusive block range in volume x
  const int copy_lo = std::max(x_lo, 0), copy_hi = std::min(x_hi, dx - 1);
  // y and z only as far as the mesher reads (cells + 1): a thin volume's chunks are thin.
  for (int bz = -1; bz <= out.cells[2] + 1; ++bz) {
    const int vz = std::clamp(o[2] + bz, 0, dz - 1);
    for (int by = -1; by <= out.cells[1] + 1; ++by) {
      const size_t row = static_cast<size_t>(std::clamp(o[1] + by, 0, dy - 1)) +
                         static_cast<size_t>(dy) * static_cast<size_t>(vz);
      world::Density* dst = out.density.get() + PaddedBlock::index(-1, by, bz);
      const int before = copy_lo - x_lo, n = copy_hi - copy_lo + 1;
      copy_row(row, static_cast<size_t>(copy_lo), static_cast<size_t>(n), dst + before);
      for (int b = 0; b < before; ++b) dst[b] = dst[before];  // x below 0: sample 0
      for (int b = before + n; b <= x_hi - x_lo; ++b) dst[b] = dst[before + n - 1];
    }
  }
}

// Meshes every chunk of a volume of `dims` samples, a z-layer of chunks at a time (in
// parallel within the layer), and welds them. after_layer(z) is called once the chunks
// of layer z are meshed: no sample below z-plane 32 (z + 1) - 1 is read again.
template <class CopyRow>
ChunkMesh mesh_chunks(const std::array<int, 3>& dims, bool zero_is_solid, int threads,
                      const CopyRow& copy_row, const std::function<void(int)>& after_layer) {
  std::array<int, 3> chunks{};
  for (int a = 0; a < 3; ++a) chunks[a] = std::max(0, (dims[a] - 1 + kChunkSize - 1) / kChunkSize);
  const size_t per_layer = static_cast<size_t>(chunks[0]) * chunks[1];
  std::vector<ChunkMesh> parts(per_layer * chunks[2]);
  tbb::enumerable_thread_specific<std::unique_ptr<Worker>> workers(
      [] { return std::make_unique<Worker>(); });
  tbb::task_arena arena(arena_concurrency(threads));
  for (int cz = 0; cz < chunks[2]; ++cz) {
    parallel_for_index(arena, per_layer, [&](size_t j) {
      Worker& w = *workers.local();
      if (!w.materials_set) {
        std::fill_n(w.block.material.get(), kBlockVolume, world::Material{1});
        w.materials_set = true;
      }
      const std::array<int, 3> origin{static_cast<int>(j % chunks[0]) * kChunkSize,
                                      static_cast<int>(j / chunks[0]) * kChunkSize,
                                      cz * kChunkSize};
      for (int a = 0; a < 3; ++a) w.block.cells[a] = std::min(kChunkSize, dims[a] - 1 - origin[a]);
      w.block.zero_is_solid = zero_is_solid;
      gather_block(dims, origin, w.block, copy_row);
      mesh_chunk(w.block, w.scratch, parts[per_layer * cz + j]);
    });
    if (after_layer) after_layer(cz);
  }
  return weld_chunk_grid(parts, chunks, Vec3f{}, threads);
}

}  // namespace

float volume_scale(const FloatVolumeView& v, const VolumeMeshOptions& options) {
  const size_t n = v.values.size(), blocks = (n + kScanBlock - 1) / kScanBlock;
  tbb::task_arena arena(arena_concurrency(options.threads));
  std::vector<uint32_t> block_max(blocks, 0);
  parallel_for_index(arena, blocks, [&](size_t b) {
    const size_t begin = b * kScanBlock, end = std::min(n, begin + kScanBlock);
    block_max[b] = largest_distance_bits(v.values.data(), begin, end, options.iso);
    if (v.release) v.release(begin, end);
  });
  const float scale =
      blocks == 0 ? 0.0f
                  : std::bit_cast<float>(*std::max_element(block_max.begin(), block_max.end()));
  if (!std::isfinite(scale)) {
    const auto bad =
        std::find_if(v.values.begin(), v.values.end(), [](float x) { return !std::isfinite(x); });
    if (bad == v.values.end())
      throw std::domain_error("values too far from the iso level for float32 arithmetic");
    throw std::domain_error("value " + std::to_string(bad - v.values.begin()) + " is not finite");
  }
  return scale;
}

QuantizedVolume quantize_samples(std::array<int, 3> dims, std::span<const float> values,
                                 const VolumeMeshOptions& options) {
  const Quantizer quantizer(options, volume_scale({dims, values, {}}, options));
  const size_t n = values.size(), blocks = (n + kScanBlock - 1) / kScanBlock;
  QuantizedVolume q;
  q.dims = dims;
  q.zero_is_solid = !options.invert;
  q.density.resize(n);
  tbb::task_arena arena(arena_concurrency(options.threads));
  parallel_for_index(arena, blocks, [&](size_t b) {
    const size_t begin = b * kScanBlock;
    quantizer.run(values.data() + begin, std::min(n, begin + kScanBlock) - begin,
                  q.density.data() + begin);
  });
  return q;
}

QuantizedVolume quantize_volume(const Volume& volume, const VolumeMeshOptions& options) {
  return quantize_samples(volume.dims, volume.values, options);
}

ChunkMesh mesh_volume(const QuantizedVolume& volume, int threads) {
  const auto copy_row = [&](size_t row, size_t first, size_t n, world::Density* dst) {
    std::memcpy(dst, volume.density.data() + row * volume.dims[0] + first,
                n * sizeof(world::Density));
  };
  return mesh_chunks(volume.dims, volume.zero_is_solid, threads, copy_row, {});
}

ChunkMesh mesh_float_volume(const FloatVolumeView& v, const VolumeMeshOptions& options) {
  const Quantizer quantizer(options, volume_scale(v, options));
  const size_t dx = static_cast<size_t>(v.dims[0]), plane = dx * static_cast<size_t>(v.dims[1]);
  const auto copy_row = [&](size_t row, size_t first, size_t n, world::Density* dst) {
    quantizer.run(v.values.data() + row * dx + first, n, dst);
  };
  size_t released = 0;  // samples below this were handed to v.release
  const auto after_layer = [&](int cz) {
    const size_t keep_from = std::min(
        v.values.size(), static_cast<size_t>(std::max(0, kChunkSize * (cz + 1) - 1)) * plane);
    if (keep_from > released) v.release(released, keep_from);
    released = std::max(released, keep_from);
  };
  return mesh_chunks(
      v.dims, !options.invert, options.threads, copy_row,
      v.release ? std::function<void(int)>(after_layer) : std::function<void(int)>());
}

float value_percentile(std::span<const float> values, double p) {
  if (values.empty()) return 0.0f;
  if (const auto bad =
          std::find_if(values.begin(), values.end(), [](float v) { return !std::isfinite(v); });
      bad != values.end()) {
    throw std::domain_error("value " + std::to_string(bad - values.begin()) + " is not finite");
  }
  const size_t rank = static_cast<size_t>(
      std::llround(std::clamp(p, 0.0, 100.0) / 100.0 * static_cast<double>(values.size() - 1)));
  const auto [lo_it, hi_it] = std::minmax_element(values.begin(), values.end());
  const float lo = *lo_it, hi = *hi_it;
  if (lo == hi) return lo;
  // Bin by value, find the bin holding the rank, then select exactly among its values.
  constexpr size_t kBins = 1 << 16;
  const double scale = static_cast<double>(kBins) / (static_cast<double>(hi) - lo);
  auto bin_of = [&](float v) {
    return std::min(kBins - 1, static_cast<size_t>((static_cast<double>(v) - lo) * scale));
  };
  std::vector<size_t> count(kBins, 0);
  for (float v : values) ++count[bin_of(v)];
  size_t bin = 0, below = 0;
  while (below + count[bin] <= rank) below += count[bin++];
  std::vector<float> in_bin;
  in_bin.reserve(count[bin]);
  for (float v : values)
    if (bin_of(v) == bin) in_bin.push_back(v);
  auto nth = in_bin.begin() + static_cast<std::ptrdiff_t>(rank - below);
  std::nth_element(in_bin.begin(), nth, in_bin.end());
  return *nth;
}

void apply_spacing(ChunkMesh& mesh, const std::array<float, 3>& spacing) {
  const float sx = spacing[0], sy = spacing[1], sz = spacing[2];
  for (Vec3f& p : mesh.positions) p = {p.x * sx, p.y * sy, p.z * sz};
  for (Vec3f& n : mesh.normals) {
    const Vec3f m{n.x / sx, n.y / sy, n.z / sz};
    const float len = std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z);
    if (len > 0.0f) n = {m.x / len, m.y / len, m.z / len};
  }
}
}  // namespace vox::mesh
