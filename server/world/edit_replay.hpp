// Applying a logged edit to a chunk map outside the pipeline (the world tools' verify):
// the same steps as the pipeline, so the samples come out bit-identical to the server's.
#pragma once

#include <span>
#include <vector>

#include "server/world/chunk_map.hpp"
#include "server/world/edit.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::world {

// Generates the chunks `edit` touches (and, for a smooth, reads) that `map` lacks, then
// applies it to every touched chunk but the samples inside `keep` (the protected regions
// it was clipped by). Returns the chunks whose samples changed. Call only on a valid edit.
// `zone_chunks`: a cluster world's zone size (a smooth reads within each sample's zone;
// SampleSnapshot). Single-threaded.
std::vector<ChunkCoord> replay_edit(ChunkMap& map, const TerrainGenerator& generator,
                                    const Edit& edit, std::span<const VoxelBox> keep = {},
                                    int zone_chunks = 0);

}  // namespace vox::world
