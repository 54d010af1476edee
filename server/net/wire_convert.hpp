// Conversions between protobuf messages and world/pipeline types, with the checks that
// belong to the wire (material ranges, unknown enum values, unknown fields).
#pragma once

#include <google/protobuf/message.h>

#include <optional>
#include <string>
#include <vector>

#include "server/pipeline/world_pipeline.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"
#include "voxel.pb.h"

namespace vox::net {

inline constexpr uint32_t kProtocolVersion = 1;

wire::ChunkCoord to_wire(world::ChunkCoord c);
world::ChunkCoord from_wire(const wire::ChunkCoord& c);

// The world edit an Edit message asks for, or the status and reason to refuse it with.
struct WireEdit {
  std::optional<world::Edit> edit;
  wire::EditResult::Status status = wire::EditResult::ACCEPTED;
  std::string reason;
  bool unknown_enum = false;  // also worth an Error UNKNOWN_ENUM
};
WireEdit edit_from_wire(const wire::Edit& e);

wire::EditResult::Status status_of(world::RefusalReason r);
// The EditResult message of the pipeline's answer to request `request`: its status (a
// busy or unavailable store says when to retry), reason, the chunks given new meshes and
// the regions that clipped it.
wire::Envelope edit_result_message(uint64_t request, const pipeline::EditResult& r);

wire::Region to_wire(const world::Region& r);
// The region a RegionCommand asks to add (not validated: the pipeline does that).
world::Region region_from_wire(const wire::Region& r);
wire::RegionResult::Status status_of(pipeline::RegionOutcome::Status s);

// True when the message or any message inside it carries fields this protocol version
// does not define.
bool has_unknown_fields(const google::protobuf::Message& m);

}  // namespace vox::net
