// One batch of edits as it goes through the pipeline: applied (with what each edit
// overwrote, to undo it), re-meshed, appended to the store, and answered once durable (or
// undone and refused). Plain data; the pipeline thread owns each batch.
#pragma once

#include <array>
#include <chrono>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/store_appender.hpp"
#include "server/store/world_store.hpp"
#include "server/world/chunk.hpp"
#include "server/world/edit.hpp"
#include "server/world/material_volume.hpp"

namespace vox::pipeline {

using Clock = std::chrono::steady_clock;

struct EditResult {
  bool accepted = false;
  world::RefusalReason reason = world::RefusalReason::kNone;
  std::string message;                            // why it was refused
  std::vector<world::ChunkCoord> changed_chunks;  // chunks given a new mesh version
  // Protected regions whose samples it left as they were (it was clipped; world/region.hpp).
  std::vector<uint64_t> clipped_by;
  // Accepted as a resend of an edit applied already (its edit id): nothing changed now.
  bool already_applied = false;
  // A cluster node's refusal: the zone is not writable here just now (docs/CLUSTER.md).
  bool zone_moving = false;
  // What the edit cost the server beyond its samples, charged to its sender: chunks of
  // terrain generated for it, and uniform chunks it turned into full ones.
  size_t chunks_generated = 0, chunks_expanded = 0;
  // Accepted: what it removed and added of each material (world/material_volume.hpp).
  std::vector<world::MaterialVolume> volumes;
};

// The answer to a QueryTask: refused (kOverBudget: it reached more chunks not in memory
// than one query loads, those it loaded stay; kServerBusy; kStorageUnavailable;
// kShuttingDown) or the ray's hit, or the box's samples.
struct QueryAnswer {
  world::RefusalReason reason = world::RefusalReason::kNone;
  std::string message;
  uint32_t retry_after_ms = 0;  // a refusal's, when the pipeline knows it (0: the default)
  mesh::RayHit hit;
  std::string densities, materials;
};

// What a batch's edits overwrote, to undo the batch when the store could not make it
// durable: per edit and touched chunk, the samples of the edit's box in it (or the chunk's
// one sample when it was uniform), undone in reverse.
struct Undo {
  struct Patch {
    world::ChunkCoord coord;
    bool modified, unsaved;  // the chunk's flags before the edit
    bool was_uniform;
    world::Sample uniform;               // when was_uniform
    std::array<int, 3> lo, hi;           // chunk-local, inclusive (when !was_uniform)
    std::vector<world::Sample> samples;  // x fastest (when !was_uniform)
  };
  std::vector<Patch> patches;  // in the order the edits applied
  // Before an edit changes chunk `c`: what it may overwrite (the box within the chunk).
  void save(world::ChunkCoord c, const world::Chunk& chunk, const world::VoxelBox& box,
            bool modified, bool unsaved);
};

// Counts of what the pipeline did, added to its stats as they happen.
struct BatchCounts {
  uint64_t edits_applied = 0, edits_refused = 0, edits_refused_busy = 0, meshes_published = 0,
           chunks_generated = 0;
};

// `edited_at`: per chunk, when the oldest edit that dirtied it was submitted.
using EditTimes = std::unordered_map<world::ChunkCoord, Clock::time_point, world::ChunkCoordHash>;
using FreshMeshes = std::vector<std::shared_ptr<MeshVersion>>;  // null: mesh unchanged

struct EditBatch {
  std::vector<OrderedTask> tasks;
  std::vector<EditResult> results;                         // per task
  std::vector<std::vector<world::ChunkCoord>> edit_dirty;  // per task; may repeat
  std::vector<world::ChunkCoord> dirty;                    // sorted, unique once re-meshed
  std::vector<const EditTask*> accepted;                   // in the order they applied
  std::vector<std::vector<world::VoxelBox>> keep;          // per accepted edit: clipped
  RegionChanges regions;                                   // what its region tasks changed
  // A rollback's first slice: its record, logged after the first `before` accepted edits.
  struct Record {
    size_t before = 0;
    std::vector<uint64_t> undoes;
    std::string by;
  };
  std::optional<Record> record;
  FreshMeshes fresh;
  EditTimes edited_at;  // per dirty chunk, its oldest edit
  Undo undo;
  BatchCounts counts;
  bool any_edit = false;
  bool zone_moved = false;                    // undone because a cluster zone moved to another node
  store::WorldStore::SeqRange seqs;           // of the accepted edits, when appended
  std::shared_future<AppendOutcome> outcome;  // invalid: nothing to append
  Clock::time_point appended_at;              // when the append started
  double waited = 0;                          // seconds the pipeline stood waiting for it
};

}  // namespace vox::pipeline
