// The world as a level-of-detail chunk sees it: the generator's terrain, with the samples
// of the chunks that differ from it (modified level-0 chunks) laid over it. A coarse
// sample at a point of a modified chunk is that chunk's sample there, so every level shows
// the edits.
#pragma once

#include <functional>
#include <unordered_set>

#include "server/world/chunk.hpp"
#include "server/world/grid_cache.hpp"
#include "server/world/point_sampler.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::world {

class OverlaySampler : public PointSampler {
 public:
  using ModifiedSet = std::unordered_set<ChunkCoord, ChunkCoordHash>;
  // A modified chunk's samples; throws when it cannot give them (never generated terrain
  // in place of an edit).
  using Lookup = std::function<const Chunk&(ChunkCoord)>;

  // `modified`: every chunk that differs from the generated terrain. Both are read during
  // sample_grid only; the caller keeps them unchanged meanwhile. `cache` (optional) keeps
  // the generator's grids for the next call with the same grid.
  OverlaySampler(const TerrainGenerator& generator, const ModifiedSet& modified, Lookup lookup,
                 GridCache* cache = nullptr)
      : generator_(generator), modified_(modified), lookup_(std::move(lookup)), cache_(cache) {}

  // Any thread, as long as `lookup` may be called from it.
  void sample_grid(const std::array<int32_t, 3>& origin, int32_t step, const std::array<int, 3>& n,
                   Sample* out) const override;

 private:
  void overlay(ChunkCoord c, const std::array<int32_t, 3>& origin, int32_t step,
               const std::array<int, 3>& n, Sample* out) const;

  const TerrainGenerator& generator_;
  const ModifiedSet& modified_;
  Lookup lookup_;
  GridCache* cache_;
};

}  // namespace vox::world
