// A zone's committed records applied to the world (cluster mode, docs/CLUSTER.md): facts
// already durable in the zone's log, applied as the restore replays a log — with the
// samples each kept, no validation, budget or undo — in order, stopping at the first that
// cannot be applied (memory, an unreadable stored chunk; the caller tries it again
// later). Pipeline thread only.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/edit_step.hpp"
#include "server/pipeline/zone_authority.hpp"

namespace vox::pipeline {

class ProtectedRegions;

struct AppliedRecords {
  EditBatch batch;  // the chunks to re-mesh and publish (no tasks, nothing to append)
  // The last record applied (records.edits.front().seq - 1: none; 0 when the checkpoint
  // could not be installed).
  uint64_t through = 0;
  std::vector<world::VoxelBox> touched;  // the applied records' boxes (the coarse levels')
};

// A checkpoint that cannot be installed (a chunk that does not decode or lies outside its
// zone) is logged and nothing of the records is applied (through 0).
AppliedRecords apply_zone_records(EditWorld& world, const ZoneRecords& records,
                                  Clock::time_point now);

// One turn: the records waiting, a few reads of them at most, each applied and handed to
// `publish` (re-mesh, publish, tell the coarse levels) before `zones` hears of it. A log
// that cannot be read is logged (at most every 10 s) and left for a later turn.
void zone_records_turn(ZoneAuthority& zones, EditWorld world, Clock::time_point now,
                       const std::function<void(AppliedRecords&)>& publish);

// With no append in flight: the cluster's protected regions, when another node changed
// them, become the table `regions` clips edits by. One that cannot be read is logged (at
// most every 10 s) and read again later.
void take_zone_regions(ZoneAuthority& zones, ProtectedRegions& regions, Clock::time_point now);

}  // namespace vox::pipeline
