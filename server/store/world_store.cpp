#include "server/store/world_store.hpp"

#include <set>

#include "server/store/chunk_codec.hpp"
#include "server/store/edit_codec.hpp"
#include "server/store/postgres_store.hpp"
#include "server/store/sqlite_store.hpp"
#include "server/store/store_schema.hpp"
#include "server/store/world_store_checks.hpp"

namespace vox::store {

bool is_postgres_uri(const std::string& where) {
  return where.starts_with("postgresql://") || where.starts_with("postgres://");
}

world::Chunk read_checkpointed_chunk(WorldStore& s, world::ChunkCoord c) {
  const std::optional<ChunkRecord> record = s.read_chunk(c);
  std::string why = "no record of it";
  std::optional<world::Chunk> chunk = record ? decode_chunk(record->samples, &why) : std::nullopt;
  if (!chunk)
    throw StoreError(s.name() + ": checkpointed chunk (" + std::to_string(c.x) + ", " +
                     std::to_string(c.y) + ", " + std::to_string(c.z) +
                     ") does not read back: " + why);
  return std::move(*chunk);
}

void WorldStore::for_each_edit_back(uint64_t, uint64_t,
                                    const std::function<bool(const LoggedEdit&)>&) {}
void WorldStore::for_each_rollback(uint64_t, const std::function<bool(const LoggedEdit&)>&) {}
std::optional<ChunkRecord> WorldStore::read_base_chunk(world::ChunkCoord) {
  throw StoreError(name() + ": keeps no history");
}
void WorldStore::advance_base(std::span<const ChunkRecord>, uint64_t) {
  throw StoreError(name() + ": keeps no history");
}
void WorldStore::reset_base() { throw StoreError(name() + ": keeps no history"); }

std::unique_ptr<WorldStore> open_world_store(const std::string& where, const OpenOptions& options) {
  if (is_postgres_uri(where)) return open_postgres_store(where, options);
  return open_sqlite_store(where, options);
}

uint64_t parse_meta_u64(const std::string& store, const char* key, const std::string& value) {
  size_t used = 0;
  unsigned long long v = 0;
  try {
    v = std::stoull(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size() || value[0] == '-')
    throw StoreError(store + ": metadata '" + key + "' is not a number: '" + value + "'");
  return v;
}

void check_meta(const std::string& store, const Meta& meta, const OpenOptions& options) {
  for (const char* key : {schema::kMetaSchemaVersion, schema::kMetaSeed})
    if (!meta.contains(key)) throw StoreError(store + ": metadata '" + key + "' missing");
  const uint64_t version =
      parse_meta_u64(store, schema::kMetaSchemaVersion, meta.at(schema::kMetaSchemaVersion));
  if (version > static_cast<uint64_t>(kSchemaVersion)) {
    throw StoreError(store + ": schema version " + std::to_string(version) +
                     " is newer than this voxeld's (" + std::to_string(kSchemaVersion) +
                     "); use a newer voxeld");
  }
  const uint64_t seed = parse_meta_u64(store, schema::kMetaSeed, meta.at(schema::kMetaSeed));
  if (options.seed && *options.seed != seed) {
    throw StoreError(store + ": the world was created with seed " + std::to_string(seed) +
                     ", not " + std::to_string(*options.seed) + " (--seed); start it with --seed " +
                     std::to_string(seed) + " or use another --world");
  }
}

WorldInfo info_from_meta(const std::string& store, const Meta& meta) {
  check_meta(store, meta, {});
  WorldInfo i;
  i.seed = parse_meta_u64(store, schema::kMetaSeed, meta.at(schema::kMetaSeed));
  if (auto it = meta.find(schema::kMetaStarts); it != meta.end())
    i.starts = parse_meta_u64(store, schema::kMetaStarts, it->second);
  if (auto it = meta.find(schema::kMetaCheckpointSeq); it != meta.end())
    i.checkpoint_seq = parse_meta_u64(store, schema::kMetaCheckpointSeq, it->second);
  if (auto it = meta.find(schema::kMetaBaseSeq); it != meta.end())
    i.base_seq = parse_meta_u64(store, schema::kMetaBaseSeq, it->second);
  i.last_seq = i.checkpoint_seq;
  return i;
}

size_t distinct_coords(std::span<const ChunkRecord> chunks) {
  std::set<world::ChunkCoord> coords;
  for (const ChunkRecord& r : chunks) coords.insert(r.coord);
  return coords.size();
}

std::string join_owners(const std::vector<std::string>& owners) {
  std::string out;
  for (const std::string& o : owners) {
    if (!out.empty()) out += '\n';
    out += o;
  }
  return out;
}

std::vector<std::string> split_owners(const std::string& column) {
  std::vector<std::string> owners;
  size_t from = 0;
  while (from < column.size()) {
    const size_t end = std::min(column.find('\n', from), column.size());
    owners.push_back(column.substr(from, end - from));
    from = end + 1;
  }
  return owners;
}

world::Region check_stored_region(const std::string& store, world::Region r) {
  if (auto why = world::validate_region(r, world::EditLimits{}, world::RegionLimits{}))
    throw StoreError(store + ": region " + std::to_string(r.id) + ": " + *why);
  return r;
}

RegionTable check_region_table(const std::string& store, std::vector<world::Region> regions,
                               uint64_t next_id_meta) {
  if (regions.size() > world::RegionLimits{}.max_regions)
    throw StoreError(store + ": " + std::to_string(regions.size()) +
                     " protected regions, more than a world may have");
  RegionTable t{std::move(regions), std::max<uint64_t>(next_id_meta, 1)};
  for (const world::Region& r : t.regions) t.next_id = std::max(t.next_id, r.id + 1);
  return t;
}

void decode_logged_edit(const std::string& store, std::span<const uint8_t> bytes, LoggedEdit& e) {
  std::string why;
  auto record = decode_edit_record(bytes, &why);
  if (!record) throw StoreError(store + ": logged edit " + std::to_string(e.seq) + ": " + why);
  e.edit = std::move(record->edit);
  e.keep = std::move(record->keep);
}

void decode_logged_rollback(const std::string& store, std::span<const uint8_t> bytes,
                            LoggedEdit& e) {
  std::string why;
  auto seqs = decode_seq_list(bytes, &why);
  if (!seqs || seqs->back() >= e.seq)
    throw StoreError(store + ": rollback record " + std::to_string(e.seq) + ": " +
                     (seqs ? "undoes a later edit" : why));
  e.undoes = std::move(*seqs);
}

void log_bounds(const int64_t (&b)[4], bool (&null)[4], WorldInfo& i) {
  uint64_t lo = 0, hi = 0;
  for (int k = 0; k < 4; k += 2) {
    if (null[k]) continue;
    lo = lo == 0 ? static_cast<uint64_t>(b[k]) : std::min(lo, static_cast<uint64_t>(b[k]));
    hi = std::max(hi, static_cast<uint64_t>(b[k + 1]));
  }
  i.logged_edits = hi == 0 ? 0 : hi - lo + 1;
  i.last_seq = std::max(i.checkpoint_seq, hi);
}

}  // namespace vox::store
