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
world::Edit decode_logged_edit(const std::string& store, uint64_t seq,
                               std::span<const uint8_t> bytes);

}  // namespace vox::store
