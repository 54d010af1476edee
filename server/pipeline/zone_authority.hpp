// What the pipeline asks of a cluster node about zones (docs/CLUSTER.md); null in
// PipelineConfig: a single node, every edit its own. The node (server/cluster) implements
// it: which zones it may write now, and the committed records its world must apply before
// a zone becomes writable (a zone just taken: what earlier owners logged; an append whose
// outcome was in doubt: whatever of it landed).
//
// Threads: the pipeline thread calls every member; `set_wake` once, from the pipeline's
// constructor (the node calls the function it was given, from any thread, when records
// wait).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/checkpoints.hpp"
#include "server/store/world_store.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/zone.hpp"

namespace vox::pipeline {

// A zone's committed records to apply, in its log's order.
struct ZoneRecords {
  world::ZoneId zone;
  uint64_t epoch = 0;  // the node's epoch of the zone when read; 0: a zone it follows
  // Nothing to apply: the world forgets what it has of the zone (its changed chunks leave
  // memory or go back to the generated terrain; none is read back from the store), and
  // then has none of its records. A zone neither held nor followed any more, or lost after
  // a chunk of it was evicted (docs/CLUSTER.md, "Evicting a zone's chunks").
  bool fresh = false;
  // First, the zone's checkpoint when the world is behind it (docs/CLUSTER.md, "Zone
  // checkpoints"): every chunk its records changed through record `installed`, each
  // replacing the world's copy (the zone's other chunks were never changed through it).
  std::optional<store::ZoneCheckpoint> checkpoint;
  std::vector<store::LoggedEdit> edits;  // seq: the zone's sequence numbers
  uint64_t through = 0;                  // the last record read (the zone's log had no more)
};

class ZoneAuthority {
 public:
  virtual ~ZoneAuthority() = default;
  virtual void set_wake(std::function<void()> wake) = 0;
  // The world's zone size (chunks a side): a smooth reads within each sample's zone.
  virtual int zone_chunks() const = 0;
  // What becomes of an edit whose touched box is `box` (a smooth: its read box): applied
  // and logged here (leaving the samples in `keep` as they are: those of a part's other
  // zones); refused (`why` says so for the player), or refused because a zone is not
  // writable here just now (being loaded, handed off: a gateway asks again); forwarded to
  // the nodes that hold its zones, which then answer it (the node took task.done); or
  // answered as accepted without applying it again (its edit id was applied here already).
  enum class Verdict { kWritable, kRefused, kNotHere, kForwarded, kAlreadyApplied };
  virtual Verdict admit(EditTask& task, const world::VoxelBox& box,
                        std::vector<world::VoxelBox>& keep, std::string& why) = 0;
  // An edit admitted writable was applied (after admit, in the same batch).
  virtual void accepted(const EditTask& task) = 0;
  // An accepted edit was undone (its batch's append failed, or one before it did).
  virtual void undone(const EditTask& task) = 0;
  // A checkpoint starts (every batch answered; `seq`: the pipeline's last edit): the zones
  // whose chunks it writes now (the node notes each one's epoch and last record applied,
  // for its store's write_checkpoint).
  virtual CheckpointScope checkpoint_scope(uint64_t seq) = 0;
  // Whether a saved changed chunk may be evicted now (read back from its zone's
  // checkpoint later: only while its zone is held and caught up); true notes that it was.
  virtual bool may_evict(world::ChunkCoord c) = 0;
  // Session `owner`'s view of chunks within `radius` of `center` (radius < 0: it has none
  // any more): the node asks for its zones
  // (it shows a zone as its log has it only while it holds it, for now).
  virtual void viewing(uint64_t owner, world::ChunkCoord center, int radius) = 0;
  // Whether records wait to be applied (the pipeline then lets its batches in flight land
  // first: a zone's records apply on the world as its durable edits left it).
  virtual bool records_waiting() = 0;
  // Whether another node changed the cluster's protected regions since the table the
  // pipeline clips edits by (docs/CLUSTER.md, "Protected regions"): the pipeline then lets
  // its appends in flight land (clipped by the old table) and takes the new one.
  virtual bool regions_changed() = 0;
  // With no append in flight: the cluster's protected regions now, by which the pipeline
  // clips edits from now on; nullopt when they are still those it has. Throws
  // store::StoreError (tried again later).
  virtual std::optional<store::RegionTable> take_regions() = 0;
  // The next records to apply (at most a few thousand; call again for more), or nullopt.
  // Throws store::StoreError when the log cannot be read (tried again later).
  virtual std::optional<ZoneRecords> next_records() = 0;
  // The pipeline applied them through record `through` (short of records.through when one
  // could not be applied: memory, an unreadable stored chunk; the rest is tried again).
  virtual void applied(const ZoneRecords& records, uint64_t through) = 0;
};

}  // namespace vox::pipeline
