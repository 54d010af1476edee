#include "server/mesh/lod_block.hpp"

#include <stdexcept>

namespace vox::mesh {
namespace {

using world::kChunkSize;

// Samples the box [lo, lo + n) of the seam grid (half-cell units) into the block.
void sample_seam_box(const world::PointSampler& sampler, const std::array<int32_t, 3>& origin,
                     int32_t half, const std::array<int, 3>& lo, const std::array<int, 3>& n,
                     LodBlock& out) {
  out.staging.resize(static_cast<size_t>(n[0]) * n[1] * n[2]);
  sampler.sample_grid(
      {origin[0] + half * lo[0], origin[1] + half * lo[1], origin[2] + half * lo[2]}, half, n,
      out.staging.data());
  const world::Sample* s = out.staging.data();
  for (int z = 0; z < n[2]; ++z)
    for (int y = 0; y < n[1]; ++y)
      for (int x = 0; x < n[0]; ++x, ++s) {
        const int i = LodBlock::seam_index(lo[0] + x, lo[1] + y, lo[2] + z);
        out.seam_density[i] = s->density;
        out.seam_material[i] = s->material;
      }
}

}  // namespace

LodBlock::LodBlock()
    : seam_density(new world::Density[kSeamVolume]),
      seam_material(new world::Material[kSeamVolume]) {}

void gather_lod_block(const world::PointSampler& sampler, const world::LodChunk& c,
                      world::LodSeams seams, LodBlock& out) {
  if (c.level < 0 || c.level > 20 || (c.level == 0 && !seams.empty()))
    throw std::invalid_argument("gather_lod_block: bad level or seams");
  seams = world::normalized(seams);
  const auto lo64 = c.lo();
  for (int a = 0; a < 3; ++a) {  // every sampled point, padding included, fits in int32
    const int64_t side = c.side();
    if (lo64[a] - side < -(int64_t{1} << 30) || lo64[a] + 2 * side > (int64_t{1} << 30))
      throw std::invalid_argument("gather_lod_block: chunk outside the world's coordinates");
  }
  out.chunk = c;
  out.seams = seams;
  const std::array<int32_t, 3> origin{static_cast<int32_t>(lo64[0]), static_cast<int32_t>(lo64[1]),
                                      static_cast<int32_t>(lo64[2])};
  const int32_t step = int32_t{1} << c.level;

  out.coarse.cells = {kChunkSize, kChunkSize, kChunkSize};
  out.coarse.zero_is_solid = false;
  out.staging.resize(static_cast<size_t>(kBlockVolume));
  sampler.sample_grid({origin[0] - step, origin[1] - step, origin[2] - step}, step,
                      {kBlockSide, kBlockSide, kBlockSide}, out.staging.data());
  for (int i = 0; i < kBlockVolume; ++i) {
    out.coarse.density[i] = out.staging[i].density;
    out.coarse.material[i] = out.staging[i].material;
  }
  if (seams.empty()) return;

  const int32_t half = step / 2;
  constexpr int kFine = 2 * kChunkSize;  // the last half-cell point of the chunk
  for (int f = 0; f < 6; ++f) {          // a split face: its plane and the planes either side
    if (((seams.faces >> f) & 1) == 0) continue;
    const int axis = f / 2, plane = f % 2 == 0 ? 0 : kFine;
    std::array<int, 3> lo{-1, -1, -1}, n{kSeamSide, kSeamSide, kSeamSide};
    lo[axis] = plane - 1;
    n[axis] = 3;
    sample_seam_box(sampler, origin, half, lo, n, out);
  }
  for (int e = 0; e < world::kChunkEdges; ++e) {  // a split edge: its line and around it
    if (((seams.edges >> e) & 1) == 0) continue;
    const int axis = e / 4;
    std::array<int, 3> lo{-1, -1, -1}, n{3, 3, 3};
    lo[axis] = -1;
    n[axis] = kSeamSide;
    lo[(axis + 1) % 3] = ((e & 1) != 0 ? kFine : 0) - 1;
    lo[(axis + 2) % 3] = ((e & 2) != 0 ? kFine : 0) - 1;
    sample_seam_box(sampler, origin, half, lo, n, out);
  }
}

}  // namespace vox::mesh
