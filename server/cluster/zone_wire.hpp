// What nodes tell each other about a zone over NATS (docs/CLUSTER.md): subjects, and the
// bytes of a committed record and of an owner's heartbeat. Decoding never trusts the
// bytes: a wrong version, a short message or a zone other than the subject's is refused.
//
// Layout (little-endian):
//   record     u8 version (1), u8 kind (1), u64 zone key, u64 seq, i64 unix_ms, payload
//   heartbeat  u8 version (1), u8 kind (2), u64 zone key, u64 last seq
//   regions    u8 version (1), u8 kind (3), u64 the protected regions' version (a node
//              changed them: the others read them again)
//   a record's payload, an edit: u8 version (2), u16 author length, author, u64 edit id
//   (0: none), the edit as the world store encodes it (store/edit_codec.hpp, with the
//   samples it keeps); version 1 had no edit id
//
// Pure functions: any thread.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

// "vox.<world>.zone.<key>.<what>": what is "edit", "rec" or "hb". `world` names the world
// (letters, digits, '-' and '_' only: it goes into a subject).
std::string zone_subject(const std::string& world, world::ZoneId zone, const char* what);
bool valid_world_name(const std::string& world);

// "vox.<world>.regions": the protected regions' versions.
std::string regions_subject(const std::string& world);
std::vector<uint8_t> encode_regions_version(uint64_t version);
std::optional<uint64_t> decode_regions_version(std::span<const uint8_t> bytes);

std::vector<uint8_t> encode_zone_record(world::ZoneId zone, const store::ZoneRecord& record);
std::vector<uint8_t> encode_zone_heartbeat(world::ZoneId zone, uint64_t last_seq);

struct ZoneMessage {
  world::ZoneId zone;
  bool heartbeat = false;
  store::ZoneRecord record;  // a heartbeat's last seq in record.seq, no payload
};
// nullopt when the bytes are not a message of this version (too short, unknown kind).
std::optional<ZoneMessage> decode_zone_message(std::span<const uint8_t> bytes);

}  // namespace vox::cluster
