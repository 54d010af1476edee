// Undoing logged edits (a rollback: docs/PROTOCOL.md, issue 43): the chunks some edits
// reached, recomputed as if they had never been accepted, every other edit in them applied
// again in its order, bit for bit as the pipeline applied it. Only what depends on the
// undone edits is recomputed: their chunks and, going forward, the chunks of every later
// edit that read one of those (a smooth reads around itself); and only the edits those
// chunks depend on are applied again, going backward, from the chunks as they were before
// the log's first edit. Single-threaded; pure but for the `base` it is given.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::world {

struct LoggedStep {
  const Edit* edit = nullptr;
  std::span<const VoxelBox> keep;  // the protected samples it left (its clipping)
  bool undo = false;               // this edit is to be undone
};

struct UndoResult {
  // Every chunk an undone edit (or an edit reading one) reached, as it is without them;
  // by coordinate.
  std::vector<std::pair<ChunkCoord, Chunk>> chunks;
  size_t undone = 0;      // edits undone
  size_t replayed = 0;    // edits applied again
  bool too_many = false;  // over max_chunks: nothing recomputed
};

// What undoing would change, without the base: the chunks to recompute (by coordinate)
// and how many edits would be undone. At most `max_chunks` (0: no bound; over it,
// too_many and no chunks).
struct UndoPlan {
  std::vector<ChunkCoord> chunks;
  size_t undone = 0;
  bool too_many = false;
};
UndoPlan plan_undo(std::span<const LoggedStep> log, size_t max_chunks = 0);

// `log`: every edit after the base, in order. `base(c)`: chunk c as it was before the
// log's first edit (nullopt: as the generator makes it). At most `max_chunks` chunks are
// recomputed (0: no bound); the chunks read to recompute them are not counted.
UndoResult undo_edits(std::span<const LoggedStep> log, const TerrainGenerator& generator,
                      const std::function<std::optional<Chunk>(ChunkCoord)>& base,
                      size_t max_chunks = 0, int zone_chunks = 0);

}  // namespace vox::world
