// One edit applied to the world, as a function of what it reads and writes: the world
// state, the generator for terrain it needs, the memory keeper and mesh store (room made
// by eviction, once per batch), the checkpoints (a chunk being written is preserved
// first, a changed one marked unsaved). Loads what the edit and the meshes it dirties
// need, changes the touched chunks (in parallel), and appends the chunks whose meshes
// must be rebuilt to `dirtied`. Refuses it (nothing changed) when it would generate more
// than `max_generate` chunks (kOverBudget), when what it may add (generated chunks,
// uniform chunks turned full) does not fit the memory budget even after eviction
// (kServerBusy), or when a checkpointed chunk cannot be read back (kStorageUnavailable).
// `undo`: records what it overwrites; `keep`: boxes (protected regions) it leaves as they
// are. The edit must be valid (world::validate). The pipeline thread only. undo_edits
// undoes a batch of them.
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/world/edit.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

struct WorldState;
class MemoryKeeper;
class MeshStore;
class Checkpoints;

struct EditWorld {
  WorldState& state;
  const world::TerrainGenerator& generator;
  MemoryKeeper& memory;
  MeshStore& meshes;
  Checkpoints* checkpoints;  // null without a store
  size_t other_bytes;        // sessions' state and the unaccounted heap, in the memory budget
  std::function<size_t()> resident_bytes;  // what the budget counts now
  int zone_chunks = 0;  // a cluster node's zones: a smooth reads within each sample's zone
};

// Makes `wanted` resident, as an edit needs its chunks: refused kOverBudget when more than
// `max_generate` are missing, kServerBusy when they (and `may_expand` uniform chunks turned
// full) do not fit the memory budget even after eviction, kStorageUnavailable when a stored
// chunk cannot be read back. `generated`: chunks of terrain made. Pipeline thread only.
world::RefusalReason load_chunks(EditWorld& w, const std::vector<world::ChunkCoord>& wanted,
                                 size_t max_generate, size_t may_expand, Clock::time_point now,
                                 size_t& generated);

world::RefusalReason apply_edit_step(EditWorld& w, const world::Edit& edit, Clock::time_point now,
                                     size_t max_generate, std::vector<world::ChunkCoord>& dirtied,
                                     EditResult& result, Undo* undo = nullptr,
                                     std::span<const world::VoxelBox> keep = {});

// Puts `chunk` in place of chunk c (a rollback's recomputed chunk): resident from now on,
// marked changed and unsaved; a checkpoint in flight gets a copy of what it replaces.
// Pipeline thread only.
void replace_chunk(EditWorld& w, world::ChunkCoord c, world::Chunk chunk, Clock::time_point now);
// A slice of a rollback's chunks put in place, as an edit would change them: each loaded
// first (kStorageUnavailable when a stored one cannot be read: nothing changed), its old
// samples saved in `undo`, the meshed chunks reading it appended to `dirtied`.
world::RefusalReason install_chunks(EditWorld& w,
                                    std::vector<std::pair<world::ChunkCoord, world::Chunk>>& chunks,
                                    Clock::time_point now, std::vector<world::ChunkCoord>& dirtied,
                                    Undo* undo);

// Undoes a batch's edits, last first: each chunk gets back its samples and its flags as
// they were before the batch (a chunk an edit compacted to one sample is expanded again;
// the samples outside the box were that sample already); a chunk a checkpoint in flight
// holds is preserved first. `checkpoints`: null without a store. Pipeline thread only.
void undo_edits(WorldState& state, Checkpoints* checkpoints, Undo& undo);

}  // namespace vox::pipeline
