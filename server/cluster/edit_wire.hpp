// An edit forwarded from a gateway node to the node that holds its zone, and the answer,
// as NATS request and reply bytes (docs/CLUSTER.md, "Messaging over NATS"). Decoding
// never trusts the bytes: a short or long message, an unknown version or reason, or an
// edit the world store's codec refuses is nullopt with the reason.
//
// Layout (little-endian):
//   request  u8 version (2), u8 kind (3), u64 id, u8 flags (1: bypasses protected
//            regions; 2: one zone's part), u64 edit id, [u64 the part's zone key,]
//            u16 author length, author, the edit (store/edit_codec.hpp)
//   reply    u8 version (2), u8 kind (4), u64 id, u8 reason (world::RefusalReason; 0:
//            accepted), u8 flags (1: applied already, 2: the zone is moving), u16 message length,
//            message, u16 zones, each (u64 zone key, u64 the zone's last record once the edit was
//            durable), u16 chunks, each (i32 x, y, z: chunks given a new mesh on the holder), u16
//            regions, each u64
//
// Pure functions: any thread.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

struct EditRequest {
  uint64_t id = 0;  // the forwarder's, for its answer
  bool bypass_regions = false;
  uint64_t edit_id = 0;               // the cluster-wide id its gateway gave the edit (0: none)
  std::optional<world::ZoneId> part;  // only this zone's samples: one part of an edit
  std::string author;
  world::Edit edit;
};

struct EditReply {
  uint64_t id = 0;
  world::RefusalReason reason = world::RefusalReason::kNone;  // kNone: accepted
  std::string message;
  std::vector<std::pair<world::ZoneId, uint64_t>> zones;  // where it is durable, up to which record
  std::vector<world::ChunkCoord> changed_chunks;
  std::vector<uint64_t> clipped_by;
  bool already_applied = false;  // accepted as a resend: applied before (its edit id)
  // Refused because the zone is not writable at the node that answered (handed off, or
  // its log still being applied): the gateway asks again.
  bool zone_moving = false;
  // Not on the wire: the gateway's own refusal of a request its holder never answered
  // (the edit may have been applied).
  bool maybe_applied = false;
};

std::vector<uint8_t> encode_edit_request(const EditRequest& r);
std::optional<EditRequest> decode_edit_request(std::span<const uint8_t> bytes,
                                               std::string* error = nullptr);
std::vector<uint8_t> encode_edit_reply(const EditReply& r);
std::optional<EditReply> decode_edit_reply(std::span<const uint8_t> bytes,
                                           std::string* error = nullptr);

}  // namespace vox::cluster
