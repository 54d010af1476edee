// Undoing logged edits (a rollback: docs/PROTOCOL.md, issue 43): the chunks some edits
// reached, recomputed as if they had never been accepted (or, for a rollback undone, as if
// they had been again), every other edit in them applied again in its order, bit for bit
// as the pipeline applied it. Only what depends on the changed edits is recomputed: their
// chunks and, going forward, the chunks of every later edit that read one of those (a
// smooth reads around itself); and only the edits those chunks depend on are applied
// again, going backward, from the chunks as they were before the log's first edit.
//
// The log is streamed, never held: three passes over it (forward, newest first, forward),
// so memory is the chunks and the sequence numbers of the edits applied again, whatever
// the history's length. Single-threaded; pure but for the log and the base it is given.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <unordered_set>
#include <utility>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::world {

struct LoggedStep {
  uint64_t seq = 0;  // ascending along the log
  const Edit* edit = nullptr;
  std::span<const VoxelBox> keep;  // the protected samples it left (its clipping)
  bool excluded = false;           // left out of the result
  bool changed = false;            // in the world as it is now if and only if not in the result
};

// The log's steps, oldest first (or newest first when `newest_first`), each to `visit`.
using StepSource =
    std::function<void(bool newest_first, const std::function<void(const LoggedStep&)>& visit)>;
// A source over steps held in memory (tests, benchmarks).
StepSource steps_of(std::span<const LoggedStep> log);

// A rollback record as the log has it: the sequence numbers it undoes (ascending).
struct RollbackMark {
  uint64_t seq = 0;
  std::span<const uint64_t> undoes;
};
// The sequence numbers the records leave out, given in their order: a record undone by a
// later one undoes nothing (so a rollback of a rollback brings its edits back).
std::unordered_set<uint64_t> excluded_by(std::span<const RollbackMark> records);

// What undoing would change, without the base: the chunks to recompute (by coordinate)
// and how many steps change. Over `max_chunks` (0: no bound): too_many and no chunks.
struct UndoPlan {
  std::vector<ChunkCoord> chunks;
  size_t changed = 0;
  bool too_many = false;
};
UndoPlan plan_undo(const StepSource& log, size_t max_chunks = 0);

struct UndoResult {
  // Every chunk a changed step (or a step reading one) reached, as it is in the result;
  // by coordinate.
  std::vector<std::pair<ChunkCoord, Chunk>> chunks;
  size_t changed = 0;     // steps changed
  size_t replayed = 0;    // edits applied again
  bool too_many = false;  // over max_chunks: nothing recomputed
};

// `base(c)`: chunk c as it was before the log's first step (nullopt: as the generator
// makes it). At most `max_chunks` chunks are held, those read to recompute the others
// included (0: no bound).
UndoResult undo_edits(const StepSource& log, const TerrainGenerator& generator,
                      const std::function<std::optional<Chunk>(ChunkCoord)>& base,
                      size_t max_chunks = 0, int zone_chunks = 0);

}  // namespace vox::world
