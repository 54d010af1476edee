#include "server/store/pq_regions.hpp"

#include "server/store/store_schema.hpp"
#include "server/store/world_store_checks.hpp"

namespace vox::store {

std::vector<world::Region> read_region_rows(pqxx::transaction_base& t, const std::string& table,
                                            const std::string& store) {
  std::vector<world::Region> out;
  for (const auto& row : t.exec("SELECT " VOX_REGION_COLUMNS " FROM " + table + " ORDER BY id")) {
    world::Region r;
    r.id = row[0].as<uint64_t>();
    r.name = row[1].as<std::string>();
    for (int a = 0; a < 3; ++a) {
      r.box.lo[a] = row[2 + a].as<int32_t>();
      r.box.hi[a] = row[5 + a].as<int32_t>();
    }
    const auto flags = row[8].as<int64_t>();
    r.flags = flags >= 0 && flags <= 255 ? static_cast<uint8_t>(flags) : 0xff;
    r.owners = split_owners(row[9].as<std::string>());
    r.created_by = row[10].as<std::string>();
    r.created_unix_ms = row[11].as<int64_t>();
    out.push_back(check_stored_region(store, std::move(r)));
  }
  return out;
}

void write_region_rows(pqxx::work& t, const std::string& table, const RegionWrite& w) {
  if (w.whole) t.exec("DELETE FROM " + table);
  const std::string insert =
      "INSERT INTO " + table + " (" VOX_REGION_COLUMNS ") " VOX_REGION_VALUES;
  for (const world::Region& r : w.upsert) {
    t.exec_params(insert, static_cast<int64_t>(r.id), r.name, r.box.lo[0], r.box.lo[1], r.box.lo[2],
                  r.box.hi[0], r.box.hi[1], r.box.hi[2], int{r.flags}, join_owners(r.owners),
                  r.created_by, r.created_unix_ms);
  }
  for (const uint64_t id : w.remove)
    t.exec_params("DELETE FROM " + table + " WHERE id = $1", static_cast<int64_t>(id));
}

uint64_t check_region_version(pqxx::work& t, const RegionsAt& regions, const std::string& name) {
  const pqxx::result r =
      t.exec(regions.write ? "SELECT regions_version FROM cluster_world FOR UPDATE"
                           : "SELECT regions_version FROM cluster_world");
  if (r.empty()) throw StoreError(name + ": the database holds no cluster world's settings");
  const auto now = r[0][0].as<uint64_t>();
  if (now != regions.version) {
    std::string what = name;
    what += ": the protected regions changed (now at version ";
    what += std::to_string(now);
    what += ", this write's edits were clipped at ";
    what += std::to_string(regions.version);
    what += "); write refused";
    throw RegionsChangedError(what, now);
  }
  return now;
}

}  // namespace vox::store
