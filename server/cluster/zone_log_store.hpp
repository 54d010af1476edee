// A cluster node's world store (docs/CLUSTER.md): the pipeline appends its batches here as
// it does to a single node's store, and each edit goes to the log of the zone it lies in —
// one part per zone for an edit across a border, each keeping the samples outside its
// zone — every zone fenced by the node's epoch, all in one transaction, then published.
// One part of an edit whose other zones other nodes hold (LoggedEdit::part) goes to its
// zone's log with the other parts as pending (ZonePending): their holders complete them
// should their own requests never come.
// A fenced zone is lost at once; an append whose outcome is in doubt makes its zones catch
// up from their logs again (whatever of it landed is applied; ZoneTable::doubt).
// Checkpoints (docs/CLUSTER.md, "Zone checkpoints"): the pipeline's checkpoint of the
// chunks of the zones it holds is written zone by zone, each fenced by its epoch and at
// the zone's own sequence number noted when the checkpoint started; the log is kept (no
// trimming yet). The world is read zone by zone as the node takes or follows zones (their
// checkpoints, then their logs), not at start; a changed chunk evicted from a zone held
// here is read back alone from the zone's checkpoint (read_chunk).
// Protected regions (docs/CLUSTER.md, "Protected regions"): one table for the cluster,
// versioned. Every append is refused unless the table is still at the version the
// pipeline's edits were clipped by (RegionsChangedError: no zone is lost, the edits are
// refused and the pipeline takes the table again); a batch's region changes are written
// in its append's transaction and their new version published.
//
// Threads: the pipeline's appender calls append_edits, the pipeline thread
// checkpoint_started, read_chunk and take_regions (on the pipeline thread's connection),
// the checkpoint writer's thread write_checkpoint (on its own connection); heard_regions
// and regions_stale any thread; the rest is read once, by the pipeline's constructor.
#pragma once

#include <atomic>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/cluster/zone_publisher.hpp"
#include "server/cluster/zone_table.hpp"
#include "server/store/world_store.hpp"
#include "server/store/zone_leases.hpp"

namespace vox::cluster {

class ZoneLogStore : public store::WorldStore {
 public:
  // `checkpoint_db`: the connection checkpoints are written on; `read_db`: the pipeline
  // thread's.
  ZoneLogStore(ZoneTable& zones, ZonePublisher& publisher, store::ZoneLeases& checkpoint_db,
               store::ZoneLeases& read_db, int zone_chunks, uint64_t seed, std::string name);

  // A checkpoint through the pipeline's edit `seq` starts: the zones it writes, each with
  // its epoch and last record applied (ZoneTable::start_checkpoint).
  void checkpoint_started(uint64_t seq, std::vector<ZoneTable::CheckpointZone> zones);
  uint64_t checkpoints_written() const {  // zones' checkpoints; any thread
    return written_.load(std::memory_order_relaxed);
  }

  const std::string& name() const override { return name_; }
  store::WorldInfo info() override;
  void append_edits(std::span<const store::LoggedEdit> edits, std::span<const SeqRange> forget,
                    const store::RegionWrite* regions) override;
  store::RegionTable read_regions() override;
  // Another node changed the protected regions to `version` (heard over NATS, read by the
  // keeper's round, or an append refused).
  void heard_regions(uint64_t version);
  // Whether the cluster's regions may differ from the table the pipeline clips edits by.
  bool regions_stale() const;
  // With no append in flight: the cluster's regions now, the table the pipeline clips
  // edits by from now on; nullopt when they are at the version it has (and not in doubt).
  // Throws store::StoreError.
  std::optional<store::RegionTable> take_regions();
  void write_checkpoint(std::span<const store::ChunkRecord>, uint64_t, store::LogTrim) override;
  // A changed chunk evicted from a zone held here (ZoneTable::may_evict), as the zone's
  // checkpoint has it; StoreError when that is past what the world applied of the zone.
  std::optional<store::ChunkRecord> read_chunk(world::ChunkCoord c) override {
    const world::ZoneId zone = world::zone_of(c, zone_chunks_);
    return read_db_.read_chunk(zone, c, zones_.applied(zone));
  }
  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>&) override {}
  void for_each_edit(uint64_t, const std::function<bool(const store::LoggedEdit&)>&) override {}

 private:
  ZoneTable& zones_;
  ZonePublisher& publisher_;
  store::ZoneLeases& checkpoint_db_;
  store::ZoneLeases& read_db_;
  std::mutex mutex_;  // guards started_
  std::optional<std::pair<uint64_t, std::vector<ZoneTable::CheckpointZone>>> started_;
  // The checkpoint writer's thread: per zone, the last record a checkpoint was written
  // through (a zone without new records or chunks is not written again).
  std::map<world::ZoneId, uint64_t> last_written_;
  std::atomic<uint64_t> written_{0};
  std::atomic<uint64_t> regions_version_{0};  // the version of the pipeline's table
  std::atomic<uint64_t> regions_heard_{0};    // the newest version heard of
  std::atomic<bool> regions_doubt_{false};    // a change of them may have landed, or not
  const int zone_chunks_;
  const uint64_t seed_;
  const std::string name_;
};

}  // namespace vox::cluster
