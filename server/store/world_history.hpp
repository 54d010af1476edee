// The history a world keeps for rollbacks (docs/OPERATIONS.md, "Rolling back"): the base
// chunks (the world as it was after edit base_seq) and the log of every edit and rollback
// record after it. A rollback is a record in the log naming the edits it undoes; the world
// after it is the base with every edit since applied again in its order but those the
// records leave out (a record undone by a later one leaves nothing out). Everything here
// reads the store through its own connection and runs on the caller's thread.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/store/chunk_codec.hpp"
#include "server/store/world_store.hpp"
#include "server/world/chunk.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::store {

// Which edits a rollback undoes: those matching every filter given, not undone already.
struct RollbackQuery {
  std::string player;  // by this author (empty: anyone's; "-": no author, an open server's)
  std::optional<world::VoxelBox> box;                      // reaching into these samples
  int64_t since_ms = std::numeric_limits<int64_t>::min();  // accepted at or after
  int64_t until_ms = std::numeric_limits<int64_t>::max();  // and before
  // Instead of the filters: undo this rollback record (its edits come back).
  uint64_t undo_record = 0;
};

struct RollbackOutcome {
  std::string refusal;           // not empty: nothing else is set
  std::vector<uint64_t> undoes;  // the record to log (empty: nothing matched)
  size_t edits = 0;              // edits whose place in the world changes
  bool too_many = false;         // more chunks than allowed: nothing recomputed
  // The chunks it recomputes, by coordinate; with their samples unless a dry run.
  std::vector<world::ChunkCoord> chunks;
  std::vector<std::pair<world::ChunkCoord, world::Chunk>> recomputed;
  uint64_t history_from = 0;  // the first seq the history holds (0: none logged)
  int64_t history_from_ms = 0;
};

// What undoing `query`'s edits would make of the world as of edit `through` (later edits
// are not seen: the caller keeps them off the chunks it recomputes). Throws StoreError.
RollbackOutcome prepare_rollback(WorldStore& store, const world::TerrainGenerator& generator,
                                 const RollbackQuery& query, uint64_t through, bool dry_run,
                                 size_t max_chunks, int zone_chunks = 0);

// The chunks logged rollback record `record` recomputed, as the world was right after it
// (a restart replaying the log, a verify). Throws StoreError.
std::vector<std::pair<world::ChunkCoord, world::Chunk>> replay_rollback(
    WorldStore& store, const world::TerrainGenerator& generator, const LoggedEdit& record,
    int zone_chunks = 0);

// Every rollback record after `after_seq` replayed, by seq: what a tool walking the log
// puts in place when it meets one (computed first: a connection reads one thing at a time).
std::map<uint64_t, std::vector<std::pair<world::ChunkCoord, world::Chunk>>> replay_rollbacks_after(
    WorldStore& store, const world::TerrainGenerator& generator, uint64_t after_seq);

// The history's start moves forward after a checkpoint through `checkpoint_seq`: the edits
// that left `window` (LogTrim's window; a trim of nothing keeps everything) are applied to
// the base chunks, those rollback records leave out skipped, and trimmed from the log. A
// world without a base (older, or trimmed whole before) gets one: the checkpoint. Bounded
// per call (edits and chunks); the next checkpoint goes on. Throws StoreError.
struct HistoryStep {
  bool reset = false;  // the base became the checkpoint
  uint64_t through = 0;
  size_t edits = 0, chunks = 0;
};
HistoryStep advance_history(WorldStore& store, const world::TerrainGenerator& generator,
                            const LogTrim& window, uint64_t checkpoint_seq, ChunkEncoder& encoder);

}  // namespace vox::store
