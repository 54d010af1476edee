// What both backends check and read alike: the metadata rules (schema version, seed) and
// the decoding of a logged edit. Internal to the store library.
#pragma once

#include <map>
#include <span>
#include <string>

#include "server/store/world_store.hpp"

namespace vox::store {

using Meta = std::map<std::string, std::string>;

uint64_t parse_meta_u64(const std::string& store, const char* key, const std::string& value);
// Refuses a store of a newer schema, one without the keys every world has, and (when
// options.seed is set) one of another seed, naming both seeds.
void check_meta(const std::string& store, const Meta& meta, const OpenOptions& options);
WorldInfo info_from_meta(const std::string& store, const Meta& meta);
// How many chunks `chunks` names (a coordinate listed twice is written once).
size_t distinct_coords(std::span<const ChunkRecord> chunks);
// A region's owners in one column, and back.
std::string join_owners(const std::vector<std::string>& owners);
std::vector<std::string> split_owners(const std::string& column);
// A region read back: refused (StoreError naming it) unless it is valid.
world::Region check_stored_region(const std::string& store, world::Region r);
// The table read back: at most RegionLimits::max_regions, next_id above every id.
RegionTable check_region_table(const std::string& store, std::vector<world::Region> regions,
                               uint64_t next_id_meta);
// Fills e.edit and e.keep from a log record (e.seq names it in the error).
void decode_logged_edit(const std::string& store, std::span<const uint8_t> bytes, LoggedEdit& e);
// Fills e.undoes from a rollback record (e.seq set: it undoes only earlier seqs).
void decode_logged_rollback(const std::string& store, std::span<const uint8_t> bytes,
                            LoggedEdit& e);
// WorldInfo's logged_edits and last_seq from schema::kLogBounds' four columns (null: the
// table is empty).
void log_bounds(const int64_t (&b)[4], bool (&null)[4], WorldInfo& i);

}  // namespace vox::store
