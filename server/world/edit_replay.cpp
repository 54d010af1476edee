#include "server/world/edit_replay.hpp"

#include <optional>

#include "server/world/edit_apply.hpp"

namespace vox::world {

std::vector<ChunkCoord> replay_edit(ChunkMap& map, const TerrainGenerator& generator,
                                    const Edit& edit, std::span<const VoxelBox> keep,
                                    int zone_chunks) {
  const std::vector<ChunkCoord> touched = chunks_overlapping(touched_box(edit));
  const auto* smooth = std::get_if<Smooth>(&edit);
  const std::vector<ChunkCoord> read =
      smooth ? chunks_overlapping(smooth_read_box(*smooth)) : touched;
  for (const ChunkCoord& c : read)
    if (!map.find(c)) map.insert(c, generator.generate(c));
  std::optional<SampleSnapshot> snapshot;
  if (smooth) {
    snapshot = take_snapshot(map, smooth_read_box(*smooth));
    snapshot->zone_chunks = zone_chunks;
  }
  std::vector<ChunkCoord> changed;
  for (const ChunkCoord& c : touched) {
    Chunk& chunk = *map.find(c);
    const bool was_uniform = chunk.is_uniform();
    if (apply_edit(edit, c, chunk, snapshot ? &*snapshot : nullptr, keep).changed)
      changed.push_back(c);
    map.note_changed(was_uniform, chunk);
  }
  return changed;
}

}  // namespace vox::world
