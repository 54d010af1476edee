// A batch's edit pass, as a function of what it reads and writes: its edits, region
// changes and inspections applied in arrival order on the world (edit_step.hpp), each edit
// validated, held to the generation and memory limits and to the protected regions, or
// refused with its reason: untried while the store rests after a failure, or while the
// log's tail is at its bound. Pipeline thread only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_set>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/edit_ids.hpp"
#include "server/pipeline/edit_step.hpp"
#include "server/pipeline/query_pass.hpp"
#include "server/world/edit.hpp"

namespace vox::pipeline {

class ProtectedRegions;
class ZoneAuthority;

// What an edit refused because the store could not write is told.
inline constexpr const char* kStorageMessage =
    "the world store could not make the edit durable (disk full, database unreachable, or, on "
    "a cluster node, its zone was taken by another node or the protected regions changed "
    "meanwhile); the edit was not applied";

// The rules in force for one pass.
struct EditRules {
  const world::EditLimits& limits;
  size_t max_generated_per_owner;  // terrain one sender's edits may generate in a batch
  bool durable;                    // with a store (edits record their undo)
  bool store_resting;              // after a failed append: edits are refused untried
  uint64_t log_tail;               // logged edits no checkpoint holds (world.checkpoints)
  ZoneAuthority* zones = nullptr;  // a cluster node: edits only in the zones it may write
  EditIds* edit_ids = nullptr;     // a single node's: the edit ids it has applied
  // Chunks a rollback is recomputing: edits reaching them are refused until thawed.
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash>* frozen = nullptr;
  uint64_t last_seq = 0;  // the sequence number of the last edit logged before this batch
  QueryBudget* query_budget = nullptr;  // what queries may take of the thread (null: all)
};

// What an edit reaching a chunk a rollback recomputes is told (SERVER_BUSY: retry).
inline constexpr const char* kRollingBackMessage =
    "an admin is rolling this area back: edits here are refused for a moment; retry";

// Whether `tasks` change the protected regions (a cluster node reads its table first).
bool changes_regions(const std::vector<OrderedTask>& tasks);

// Applies `tasks` (moved into the batch) and runs its inspections; returns the batch with
// each task's result, the chunks to re-mesh and what undoes it.
EditBatch apply_edits(std::vector<OrderedTask>& tasks, EditWorld& world, ProtectedRegions& regions,
                      const EditRules& rules, Clock::time_point now);

// A batch the store could not make durable (it was undone): each edit it accepted is
// refused STORAGE_UNAVAILABLE, and nothing of it is to be published.
// Their edit ids are forgotten (`ids`: a single node's; `zones`: a cluster node's). A
// resend it answered as applied already is refused too: the original may be among the
// undone (the client sends it again).
void refuse_undone(EditBatch& b, EditIds* ids, ZoneAuthority* zones);

// Answers the batch's region tasks (refused STORAGE_UNAVAILABLE when not `durable`) and its
// edits (each with the chunks it changed among `published`).
void answer_tasks(EditBatch& b, bool durable, const std::vector<world::ChunkCoord>& published);

}  // namespace vox::pipeline
