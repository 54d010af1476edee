// What a cluster node's world must apply (docs/CLUSTER.md), handed to its pipeline
// (pipeline::ZoneAuthority::next_records and applied): the log of each zone it has just
// taken, or whose append was in doubt, to the log's end (the zone is writable then); and
// the records of the zones it follows, as their holders commit them. A zone's checkpoint
// comes first when the world should install it rather than apply the records before it
// (checkpoint_first): a zone taken or followed anew, or far behind. A zone lost after the
// node evicted a chunk of it, or one no longer viewed, is forgotten first (ZoneTable's
// fresh zones), then installed afresh when held, followed or viewed.
//
// Threads: the pipeline thread, but installed() (any thread).
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "server/cluster/zone_publisher.hpp"
#include "server/cluster/zone_replicas.hpp"
#include "server/cluster/zone_table.hpp"
#include "server/pipeline/zone_authority.hpp"
#include "server/store/zone_leases.hpp"

namespace vox::cluster {

class ZoneRecordSource {
 public:
  // `db`: the pipeline thread's connection; `store_name`: the store's, for messages.
  ZoneRecordSource(ZoneTable& table, ZoneReplicas& replicas, ZonePublisher& publisher,
                   store::ZoneLeases& db, std::string store_name);

  bool waiting() const {
    return table_.catching_up() || replicas_.waiting() || table_.next_fresh().has_value();
  }
  // The next records to apply, or nullopt. Throws store::StoreError when a log cannot be read.
  std::optional<pipeline::ZoneRecords> next();
  // The pipeline applied `records` through `through` (short of their end: the rest is
  // handed over again).
  void applied(const pipeline::ZoneRecords& records, uint64_t through);
  uint64_t installed() const { return installed_.load(std::memory_order_relaxed); }

 private:
  std::optional<pipeline::ZoneRecords> catch_up();
  // A zone lost after this node evicted a chunk of it, or neither held nor followed any
  // more (ZoneTable::fresh): the world forgets what it has of it, and installs its
  // checkpoint at once when the zone is held, followed or viewed (only its row and
  // checkpoint are read, and a failure to read them is no error: the log is applied
  // from its start then).
  pipeline::ZoneRecords fresh_records(world::ZoneId zone);
  std::optional<pipeline::ZoneRecords> followed_records();
  // The zone's checkpoint when a world with its records through `applied` should install
  // it first (checkpoint_first).
  std::optional<store::ZoneCheckpoint> checkpoint_past(world::ZoneId zone, uint64_t applied,
                                                       uint64_t checkpoint_seq);
  size_t append_run(world::ZoneId zone, const std::vector<store::ZoneRecord>& records,
                    pipeline::ZoneRecords& out, uint64_t last) const;
  void expect_next(world::ZoneId zone, const std::vector<store::ZoneRecord>& read,
                   uint64_t after) const;

  ZoneTable& table_;
  ZoneReplicas& replicas_;
  ZonePublisher& publisher_;
  store::ZoneLeases& db_;
  const std::string store_name_;
  // The followed records handed to the pipeline last (given back when it could not apply
  // them all).
  std::vector<store::ZoneRecord> handed_;
  // Per zone catching up, the log's last record when it began.
  std::map<world::ZoneId, uint64_t> targets_;
  // Per zone, a checkpoint that could not be installed (its log is applied instead).
  std::map<world::ZoneId, uint64_t> unusable_;
  bool catch_up_first_ = false;  // which kind of records the next call looks for first
  // The zones caught up and started last: the next turns begin after them.
  std::optional<world::ZoneId> caught_up_last_, started_last_;
  std::atomic<uint64_t> installed_{0};  // checkpoints installed
};

}  // namespace vox::cluster
