// A cluster node's world store (docs/CLUSTER.md): the pipeline appends its batches here as
// it does to a single node's store, and each edit goes to the log of the zone it lies in —
// one part per zone for an edit across a border, each keeping the samples outside its
// zone — every zone fenced by the node's epoch, all in one transaction, then published.
// One part of an edit whose other zones other nodes hold (LoggedEdit::part) goes to its
// zone's log with the other parts as pending (ZonePending): their holders complete them
// should their own requests never come.
// A fenced zone is lost at once; an append whose outcome is in doubt makes its zones catch
// up from their logs again (whatever of it landed is applied; ZoneTable::doubt). Nothing
// else of a single node's store is kept here yet: no protected regions, no checkpoints
// (the pipeline writes none for a cluster node), and the world is read zone by zone as the
// node takes zones, not at start.
//
// Threads: the pipeline's appender calls append_edits; the rest is read once, by the
// pipeline's constructor.
#pragma once

#include <string>

#include "server/cluster/zone_publisher.hpp"
#include "server/cluster/zone_table.hpp"
#include "server/store/world_store.hpp"

namespace vox::cluster {

class ZoneLogStore : public store::WorldStore {
 public:
  ZoneLogStore(ZoneTable& zones, ZonePublisher& publisher, int zone_chunks, uint64_t seed,
               std::string name);

  const std::string& name() const override { return name_; }
  store::WorldInfo info() override;
  void append_edits(std::span<const store::LoggedEdit> edits, std::span<const SeqRange> forget,
                    const store::RegionWrite* regions) override;
  store::RegionTable read_regions() override { return {}; }
  void write_checkpoint(std::span<const store::ChunkRecord>, uint64_t, uint64_t) override;
  std::optional<store::ChunkRecord> read_chunk(world::ChunkCoord) override { return std::nullopt; }
  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>&) override {}
  void for_each_edit(uint64_t, const std::function<bool(const store::LoggedEdit&)>&) override {}

 private:
  ZoneTable& zones_;
  ZonePublisher& publisher_;
  const int zone_chunks_;
  const uint64_t seed_;
  const std::string name_;
};

}  // namespace vox::cluster
