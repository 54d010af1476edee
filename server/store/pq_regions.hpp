// Protected regions in PostgreSQL, as a single node's store keeps them (table `regions`)
// and a cluster world does (`zone_regions`, docs/CLUSTER.md "Protected regions"): the
// rows read back, a change written, and a cluster append's check of their version. Only for the
// store's .cpp files (it includes libpqxx).
#pragma once

#include <pqxx/pqxx>
#include <string>
#include <vector>

#include "server/store/world_store.hpp"
#include "server/store/zone_leases.hpp"

namespace vox::store {

// Every row of `table`, by id, each checked (check_stored_region; StoreError names `store`).
std::vector<world::Region> read_region_rows(pqxx::transaction_base& t, const std::string& table,
                                            const std::string& store);
// A change of `table` inside the caller's transaction: one statement per region; a repair
// (w.whole), the whole table. The next id is the caller's to keep.
void write_region_rows(pqxx::work& t, const std::string& table, const RegionWrite& w);

// A cluster world's append (ZoneLeases::append), before any zone row is locked: the
// regions' version, locked when `regions.write` changes them; RegionsChangedError unless
// it is `regions.version` (`store` names the database in the message).
uint64_t check_region_version(pqxx::work& t, const RegionsAt& regions, const std::string& store);

}  // namespace vox::store
