// Which work the world pipeline runs in its next batch, in what order and within which
// budget. Pure bookkeeping (no I/O, no threads, no clock): the pipeline calls it under its
// queue lock, tests call it directly.
//
// Rules (each has a unit test in tests/batch_scheduler_test.cpp):
// - Every queued edit and inspection is in the next batch, in arrival order, whatever the
//   load backlog; loads only fill what is left.
// - Loads belong to an owner (a session's view, or a one-off load). An owner has at most
//   one pending request: a new one replaces the old (the newest view wins), and dropping
//   an owner drops its queued loads.
// - Owners are served round robin, a group of chunks per turn, each request nearest
//   first, so one big view does not delay another owner's first chunks.
// - Each session owner has a load budget (work units per second, a token bucket): an
//   owner that has spent it waits, so view floods cannot take the whole pipeline.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <string>
#include <unordered_map>
#include <variant>
#include <vector>

#include "server/mesh/surface_query.hpp"
#include "server/pipeline/token_bucket.hpp"
#include "server/world/chunk.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"
#include "server/world/zone.hpp"

namespace vox::pipeline {

struct EditResult;
struct RegionOutcome;
struct QueryAnswer;

using LoadOwner = uint64_t;

struct EditTask {
  world::Edit edit;
  std::function<void(const EditResult&)> done;
  LoadOwner owner = 0;  // the session that sent it (0: none, e.g. a test or the CLI)
  std::chrono::steady_clock::time_point submitted{};  // set by WorldPipeline::submit
  std::string author;           // the player id the edit is logged under (empty: none)
  bool bypass_regions = false;  // an admin's: protected regions do not hold it back
  bool forwarded = false;       // a cluster node sent it to this one: never forwarded on
  // A cluster's (docs/CLUSTER.md): the id its gateway gave the edit (0: none; an edit
  // already applied under its id is answered, not applied again), and, for one part of
  // an edit across zones held by different nodes, the only zone whose samples it writes.
  uint64_t edit_id = 0;
  std::optional<world::ZoneId> part;
  // A part another zone's holder logged as pending (completed here): applied as it
  // recorded it, keeping these samples, not clipped again by the protected regions (its
  // edit was accepted).
  std::optional<std::vector<world::VoxelBox>> recorded_keep;
};
// Adds a protected region (`add`, its id chosen by the pipeline) or removes one
// (`remove_id`), in order with the edits around it; durable with their batch.
struct RegionTask {
  std::optional<world::Region> add;
  uint64_t remove_id = 0;
  std::string by;  // the admin's player id, for the log
  std::function<void(const RegionOutcome&)> done;
};
struct InspectTask {
  // Runs on the pipeline thread between edits; with `cancelled` when the pipeline stopped
  // before it could run (then on whichever thread found it).
  std::function<void(bool cancelled)> run;
};
// A rollback's steps in order with the edits (pipeline/rollbacks.hpp): chunks frozen (edits
// reaching them are refused until thawed; `done` gets the sequence number of the last
// edit before the freeze), a slice of its recomputed chunks put in place (the first
// slice's batch logs the record; `done` once durable, or not: undone), or chunks thawed.
struct RollbackTask {
  enum class Kind { kFreeze, kInstall, kThaw } kind = Kind::kFreeze;
  std::vector<world::ChunkCoord> coords;                           // freeze, thaw
  std::vector<std::pair<world::ChunkCoord, world::Chunk>> chunks;  // install
  std::optional<std::vector<uint64_t>> undoes;  // install: the first slice's record
  std::string by;                               // its author
  bool last = true;                             // install: the rollback's last slice
  // Pipeline thread (or stop()'s, with ok false): freeze gives `through`; install `ok`
  // when durable.
  std::function<void(bool ok, uint64_t through)> done;
};
// A question about the samples (mesh/surface_query.hpp): a ray (a ground query is a ray
// down), or the samples of a box. Answered on the pipeline thread in order with the edits,
// from the samples they left (an edit before it may still wait for the store); chunks not
// in memory are loaded, up to a few per query.
struct QueryTask {
  std::optional<mesh::Ray> ray;
  world::VoxelBox box;  // without a ray
  // Pipeline thread (or stop()'s, refused kShuttingDown).
  std::function<void(const QueryAnswer&)> done;
};
// Edits, region changes, inspections, rollback steps and queries share one queue: each
// sees every edit queued before it.
using OrderedTask = std::variant<EditTask, InspectTask, RegionTask, RollbackTask, QueryTask>;

// Part of an owner's request taken into a batch. `done` is set on the request's last
// slice: run it once the slice's chunks are published.
struct LoadSlice {
  LoadOwner owner = 0;
  std::vector<world::ChunkCoord> chunks;
  std::function<void()> done;
};

class BatchScheduler {
 public:
  // The work a chunk still needs (0: nothing, e.g. it is meshed already). Called once per
  // chunk considered, in the order the chunks are taken, so it may count shared work once.
  using Cost = std::function<size_t(world::ChunkCoord)>;

  using Clock = std::chrono::steady_clock;
  // `owner_rate` work units per second per session owner, up to `owner_burst` (rate 0:
  // unlimited). One-off loads (owners with the top bit set) are never limited. Owners in
  // the same budget group (one address) also share `group_rate` / `group_burst`: a group's
  // budget outlives its owners until it has refilled, so reconnecting does not refill it.
  explicit BatchScheduler(size_t group = 32, double owner_rate = 0, double owner_burst = 0,
                          double group_rate = 0, double group_burst = 0)
      : group_(group),
        owner_rate_(owner_rate),
        owner_burst_(owner_burst),
        group_rate_(group_rate),
        group_burst_(group_burst) {}
  static constexpr LoadOwner kUnlimitedOwners = LoadOwner{1} << 63;

  void add(OrderedTask task);
  // Replaces `owner`'s pending request with `chunks` (nearest first). Returns the replaced
  // request's `done` (empty when none): the caller runs it, outside its locks.
  // `budget_group` (0: none) is the owner's address; an owner keeps its first group.
  std::function<void()> request(LoadOwner owner, std::vector<world::ChunkCoord> chunks,
                                std::function<void()> done = {}, uint64_t budget_group = 0);
  // Drops the owner's queued loads; returns their `done` like request().
  std::function<void()> drop(LoadOwner owner, Clock::time_point now = Clock::now());

  // A batch starts with every queued edit and inspection, in arrival order...
  std::vector<OrderedTask> take_ordered();
  // ...then takes loads: first, for up to kShortestFirstShare of `load_budget`, from the
  // owner with the fewest chunks left first (a new player's view before a huge one; of two
  // alike, the one served longer, so views finish one after another instead of all
  // together at the end); then round robin, `group` chunks per turn (so that a huge view
  // still moves), until `load_budget` is spent or `scan_limit` chunks were considered
  // (chunks of zero cost are skipped and cost no turn, but count as considered). A budget
  // of 0 takes no loads (e.g. memory is full). An owner whose budget is spent is skipped
  // until it refills.
  std::vector<LoadSlice> take_loads(size_t load_budget, const Cost& cost,
                                    size_t scan_limit = SIZE_MAX, Clock::time_point now = {});
  static constexpr double kShortestFirstShare = 0.75;
  // Whether some owner with queued loads has budget left at `now`.
  bool has_ready_loads(Clock::time_point now);

  bool has_ordered() const { return !ordered_.empty(); }
  size_t ordered_count() const { return ordered_.size(); }
  bool has_loads() const { return !rotation_.empty(); }
  size_t queued_load_chunks() const { return queued_chunks_; }
  size_t load_owners() const { return rotation_.size(); }
  size_t budget_groups() const { return groups_.size(); }  // live, or refilling after they left
  // For shutdown: every request's `done` (the ordered tasks come from take_ordered()).
  std::vector<std::function<void()>> take_all_load_callbacks();

 private:
  struct Request {
    std::vector<world::ChunkCoord> chunks;
    size_t next = 0;  // chunks before it were taken
    std::function<void()> done;
    uint64_t group = 0;  // the owner's budget group
  };

  struct GroupBudget {
    TokenBucket bucket;
    size_t owners = 0;  // live owners in the group
  };
  struct OwnerBudget {
    TokenBucket bucket;
    uint64_t group = 0;  // 0: none
  };
  OwnerBudget& budget_of(LoadOwner owner, Clock::time_point now);
  // Whether the owner may take load work now (its own and its group's budget).
  bool ready(LoadOwner owner, Clock::time_point now);
  void charge(LoadOwner owner, double work, Clock::time_point now);
  // Forgets groups without owners whose budget has refilled (equal to a fresh one).
  void purge_groups(Clock::time_point now);
  // A load pass's slices, one per owner (`at`: each owner's index in `loads`), and what it
  // spent and considered.
  struct Pass {
    std::vector<LoadSlice> loads;
    std::unordered_map<LoadOwner, size_t> at;
    size_t spent = 0, scanned = 0;
  };
  // Takes chunks of `owner`'s request into its slice of `pass` while `more()` and its
  // budget allow, at most `max_chunks`; finishes the request when its last chunk is taken.
  void take_from(LoadOwner owner, size_t max_chunks, const Cost& cost, Clock::time_point now,
                 const std::function<bool()>& more, Pass& pass);

  const size_t group_;
  const double owner_rate_, owner_burst_, group_rate_, group_burst_;
  std::unordered_map<LoadOwner, OwnerBudget> budgets_;  // session owners seen; dropped with them
  std::unordered_map<uint64_t, GroupBudget> groups_;
  std::deque<OrderedTask> ordered_;
  std::unordered_map<LoadOwner, Request> requests_;
  std::deque<LoadOwner> rotation_;  // owners with a request, next to serve at the front
  size_t queued_chunks_ = 0;
};

// The chunks within `radius` (Euclidean, chunk units) of `center`, nearest first (ties by
// coordinate, so the order is deterministic).
std::vector<world::ChunkCoord> ball_nearest_first(world::ChunkCoord center, int radius);
// Every chunk of the inclusive box [lo, hi], nearest its centre first.
std::vector<world::ChunkCoord> box_nearest_first(world::ChunkCoord lo, world::ChunkCoord hi);

}  // namespace vox::pipeline
