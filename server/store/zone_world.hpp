// A cluster world read whole, and a single node's world written into a cluster database:
// what `voxel-cli world verify` and `voxel-cli world migrate` do with a cluster world
// (docs/CLUSTER.md, "Moving in"). Tools' code: one thread, its own connection.
#pragma once

#include <cstdint>
#include <map>
#include <ostream>
#include <set>
#include <vector>

#include "server/store/zone_leases.hpp"
#include "server/world/chunk_map.hpp"

namespace vox::store {

struct ZoneWorld {
  WorldSettings settings;
  world::ChunkMap chunks;                // every chunk the zones' records changed, and some read
  std::set<world::ChunkCoord> modified;  // those changed (from the checkpoints or the logs)
  size_t zones = 0, records = 0;         // zones read, records replayed
  size_t checked = 0, mismatches = 0;    // checkpointed chunks compared with the logs
  size_t seeded = 0;  // zones whose log starts after their checkpoint (a migrated world)
};

// Every zone as its log leaves it: from the seed, each record applied in order (a smooth
// reading within each sample's zone); a zone whose log starts after record 1 (a migrated
// one) from its checkpoint. `verify`: a checkpoint the whole log reaches is compared, chunk
// by chunk, with the log replayed through it (each difference one line on `err`). Throws
// StoreError when a record does not decode, is not a valid edit, or the log has a gap.
ZoneWorld read_zone_world(ZoneLeases& db, bool verify, std::ostream& err);

// The database's world is `settings` (recorded now when it has none): StoreError naming
// the world it holds otherwise.
void settle_zone_world(ZoneLeases& db, const WorldSettings& settings);

// StoreError unless no zone of the database's world has records yet (a migration's target).
void expect_no_records(ZoneLeases& db, const WorldSettings& settings);

// Writes `chunks` (a single node's modified chunks, by coordinate) into an empty cluster
// world: the world's settings settled (StoreError when the database holds another world),
// each zone taken, given the chunks as its first checkpoint (ZoneLeases::seed_zone), and
// released. Returns the zones written.
size_t seed_zone_world(ZoneLeases& db, const WorldSettings& settings,
                       const std::map<world::ChunkCoord, const world::Chunk*>& chunks);

}  // namespace vox::store
