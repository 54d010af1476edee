// Applying a validated edit to one chunk's samples, and which chunks' meshes then change.
// Point-wise edits (brush, explosion, paint, stamp) read only the sample they write, so
// the chunks an edit touches can be processed in parallel. Smooth reads neighbours: it
// reads a snapshot taken before any chunk changes.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit.hpp"
#include "server/world/material_volume.hpp"

namespace vox::world {

// Pre-edit samples of a box (world coordinates, inclusive), x fastest.
struct SampleSnapshot {
  VoxelBox box;
  std::vector<Sample> samples;
  // A cluster world's zones (zone.hpp; 0: none): a smooth reads, around each sample, only
  // the samples of that sample's own zone (a neighbour across the zone's border is read
  // as the nearest sample inside it), so each zone's part of a smooth replays from that
  // zone's log alone (docs/CLUSTER.md, "Edits across a border").
  int zone_chunks = 0;
  Sample at(int32_t x, int32_t y, int32_t z) const;
};
SampleSnapshot take_snapshot(const ChunkMap& map, const VoxelBox& box);
// Smooth reads one sample around its touched box.
VoxelBox smooth_read_box(const Smooth& s);

// Local bounds (0..31) of the samples an edit changed in one chunk.
struct ChangedBox {
  bool changed = false;
  std::array<int, 3> lo{kChunkSize, kChunkSize, kChunkSize}, hi{-1, -1, -1};
  void add(int x, int y, int z);
};

// Applies `edit` to the samples of chunk `c` that it touches, but those inside a `keep`
// box (world coordinates: protected regions it may not change; see region.hpp), which
// keep their values. `snapshot` is required for Smooth (pre-edit values around the edit)
// and ignored otherwise. With `tally`, adds what each changed sample removed and added of
// its materials (material_volume.hpp).
ChangedBox apply_edit(const Edit& edit, ChunkCoord c, Chunk& chunk, const SampleSnapshot* snapshot,
                      std::span<const VoxelBox> keep = {}, VolumeTally* tally = nullptr);

// The chunks whose meshes read a changed sample of chunk c: c itself, and a neighbour
// across each face, edge or corner within 2 samples (its cells reach our samples 0, 1)
// or 1 sample (its gradient reaches our sample 31).
void append_dirty_chunks(ChunkCoord c, const ChangedBox& changed, std::vector<ChunkCoord>& out);

// The chunks a voxel box overlaps.
std::vector<ChunkCoord> chunks_overlapping(const VoxelBox& box);

}  // namespace vox::world
