#include "server/cluster/zone_log_store.hpp"

#include <map>

#include "server/cluster/zone_wire.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::cluster {

ZoneLogStore::ZoneLogStore(ZoneTable& zones, ZonePublisher& publisher,
                           store::ZoneLeases& checkpoint_db, store::ZoneLeases& read_db,
                           int zone_chunks, uint64_t seed, std::string name)
    : zones_(zones),
      publisher_(publisher),
      checkpoint_db_(checkpoint_db),
      read_db_(read_db),
      zone_chunks_(zone_chunks),
      seed_(seed),
      name_(std::move(name)) {}

store::WorldInfo ZoneLogStore::info() {
  store::WorldInfo out;
  out.seed = seed_;
  out.starts = 1;
  return out;
}

void ZoneLogStore::append_edits(std::span<const store::LoggedEdit> edits,
                                std::span<const SeqRange> /*forget: zones catch up instead*/,
                                const store::RegionWrite* regions) {
  std::map<world::ZoneId, ZonePublisher::Part> parts;
  for (const store::LoggedEdit& e : edits) {
    const world::VoxelBox box = world::touched_box(e.edit);
    const std::vector<world::ZoneId> all = world::zones_of(box, zone_chunks_);
    // A part's keep ends with its other zones' samples: what is left is its own.
    std::vector<world::VoxelBox> own_keep = e.keep;
    if (e.part) {
      for (const world::VoxelBox& b : world::outside_zone(box, *e.part, zone_chunks_)) {
        std::erase_if(own_keep,
                      [&](const world::VoxelBox& k) { return k.lo == b.lo && k.hi == b.hi; });
      }
    }
    const auto piece_for = [&](world::ZoneId zone) {
      store::LoggedEdit piece = e;
      piece.part.reset();
      piece.keep = own_keep;
      for (const world::VoxelBox& outside : world::outside_zone(box, zone, zone_chunks_))
        piece.keep.push_back(outside);
      return encode_zone_edit(piece);
    };
    for (const world::ZoneId zone : all) {
      if (e.part && zone != *e.part) continue;  // other nodes' parts
      ZonePublisher::Part& part = parts[zone];
      if (part.records.empty()) {
        const std::optional<uint64_t> epoch = zones_.appendable(zone);
        // Lost since the pipeline took the edit: the append fails as a fenced one would.
        if (!epoch)
          throw store::FencedError(name_ + ": zone (" + std::to_string(zone.x) + ", " +
                                       std::to_string(zone.z) + ") is no longer this node's",
                                   zone);
        part.zone = zone;
        part.epoch = *epoch;
      }
      part.records.push_back({0, e.unix_ms, piece_for(zone), e.edit_id});
      if (!e.part) continue;
      // The other zones' parts: completed by their holders should they never come.
      for (const world::ZoneId other : all) {
        if (other != zone) part.pending.push_back({other, e.edit_id, e.unix_ms, piece_for(other)});
      }
    }
  }
  std::vector<ZonePublisher::Part> list;
  list.reserve(parts.size());
  for (auto& [zone, part] : parts) list.push_back(std::move(part));
  // The records are this node's before anyone hears of them: a follower of a zone this
  // node has just lost then starts after them.
  const auto durable = [&](uint64_t regions_version) {
    for (const auto& part : list) {
      if (!part.records.empty()) zones_.committed(part.zone, part.records.back().seq);
    }
    if (regions) regions_version_ = regions_version;  // the pipeline's table's now
  };
  // Edits clipped by the pipeline's table: refused should the cluster's have changed.
  const store::RegionsAt at{regions_version_.load(), regions};
  try {
    publisher_.commit(list, durable, &at);
  } catch (const store::RegionsChangedError& e) {
    // Nothing landed. The table is read again, even should the database's version be
    // below this node's (a standby that lost a commit): else every append is refused.
    heard_regions(e.version);
    regions_doubt_ = true;
    throw;
  } catch (const store::FencedError& e) {
    for (const auto& part : list) {
      if (part.zone == e.zone) zones_.lost(part.zone, part.epoch);  // the keeper hears it too
    }
    publisher_.forget(e.zone);
    throw;
  } catch (const store::StoreError&) {
    for (const auto& part : list) zones_.doubt(part.zone);  // it may have landed
    if (regions) regions_doubt_ = true;                     // likewise: read them again
    throw;
  }
}

void ZoneLogStore::heard_regions(uint64_t version) {
  uint64_t heard = regions_heard_.load();
  while (heard < version && !regions_heard_.compare_exchange_weak(heard, version)) {
  }
}

bool ZoneLogStore::regions_stale() const {
  return regions_doubt_.load() || regions_heard_.load() > regions_version_.load();
}

store::RegionTable ZoneLogStore::read_regions() {
  store::ZoneRegions now = read_db_.read_regions();
  regions_version_ = now.version;
  heard_regions(now.version);
  return std::move(now.table);
}

std::optional<store::RegionTable> ZoneLogStore::take_regions() {
  const bool doubt = regions_doubt_.exchange(false);
  uint64_t heard = regions_heard_.load();
  try {
    store::ZoneRegions now = read_db_.read_regions();
    // A version heard before this read and above it was never committed (a node publishes
    // only after its commit): a stray message, or a database gone back. It is forgotten.
    if (heard > now.version) regions_heard_.compare_exchange_strong(heard, now.version);
    heard_regions(now.version);
    if (!doubt && now.version == regions_version_.load()) return std::nullopt;
    regions_version_ = now.version;
    return std::move(now.table);
  } catch (const store::StoreError&) {
    if (doubt) regions_doubt_ = true;
    throw;
  }
}

void ZoneLogStore::checkpoint_started(uint64_t seq, std::vector<ZoneTable::CheckpointZone> zones) {
  std::lock_guard lock(mutex_);
  started_.emplace(seq, std::move(zones));
}

void ZoneLogStore::write_checkpoint(std::span<const store::ChunkRecord> chunks, uint64_t seq,
                                    store::LogTrim /*the zones' logs are kept*/) {
  std::vector<ZoneTable::CheckpointZone> zones;
  {
    std::lock_guard lock(mutex_);
    if (!started_ || started_->first != seq)
      throw store::StoreError(name_ + ": a checkpoint through edit " + std::to_string(seq) +
                              " that did not start");
    zones = std::move(started_->second);
    started_.reset();
  }
  std::map<world::ZoneId, store::ZoneCheckpoint> by_zone;
  for (const ZoneTable::CheckpointZone& z : zones)
    by_zone[z.zone] = {.zone = z.zone, .seq = z.applied, .chunks = {}, .edit_ids = {}};
  for (const store::ChunkRecord& c : chunks) {
    const auto it = by_zone.find(world::zone_of(c.coord, zone_chunks_));
    if (it == by_zone.end())  // the pipeline writes only the zones it was given
      throw store::StoreError(name_ + ": a checkpoint's chunk outside the zones it writes");
    it->second.chunks.push_back({c.coord, it->second.seq, c.samples});
  }
  // Every zone tried; the first failure thrown (the pipeline writes the chunks again).
  std::optional<std::string> failed;
  for (const ZoneTable::CheckpointZone& z : zones) {
    store::ZoneCheckpoint& cp = by_zone[z.zone];
    const auto last = last_written_.find(z.zone);
    if (cp.seq == 0 || (cp.chunks.empty() && last != last_written_.end() && last->second >= cp.seq))
      continue;  // nothing new
    try {
      checkpoint_db_.write_checkpoint(z.epoch, cp);
      last_written_[z.zone] = cp.seq;
      written_.fetch_add(1, std::memory_order_relaxed);
    } catch (const store::StoreError& e) {
      if (!failed) failed = e.what();
    }
  }
  // Zones no longer held are forgotten (a later holding writes them anew).
  std::erase_if(last_written_, [&](const auto& entry) { return !by_zone.count(entry.first); });
  if (failed) throw store::StoreError(*failed);
}

}  // namespace vox::cluster
