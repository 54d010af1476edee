// libFuzzer target for what voxeld does with the payload of a client's frame, without
// sockets: parse the Envelope, refuse unknown fields, then per client message the checks
// and conversions of ClientSession::on_frame and its handlers (session_handlers.cpp),
// and serialize the reply the session would queue. The library functions are called as
// the session calls them; the checks written inline in the handlers (Hello's fields,
// SetView's position and radius, Resync's size, the edit's cost) are repeated here, as
// they cannot be reached without a session.
#include <google/protobuf/stubs/logging.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "server/net/client_session.hpp"
#include "server/net/log_hygiene.hpp"
#include "server/net/wire_convert.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/region.hpp"
#include "voxel.pb.h"

namespace {

using namespace vox;

const net::ServerConfig kConfig;
const world::EditLimits kLimits;  // the pipeline's default limits

void check(bool ok) {
  if (!ok) std::abort();
}

// The session frames every reply (serialized in place after the length).
void reply(const wire::Envelope& message) {
  static std::vector<uint8_t> out;
  out.resize(message.ByteSizeLong());
  message.SerializeWithCachedSizesToArray(out.data());
}

void error(wire::Error::Code code, const std::string& message) {
  (void)net::escape_for_log(message, 200);
  (void)wire::Error::Code_Name(code);
  wire::Envelope e;
  e.mutable_error()->set_code(code);
  e.mutable_error()->set_message(message);
  reply(e);
}

void result(uint64_t request, wire::EditResult::Status status, const std::string& reason) {
  wire::Envelope e;
  auto* r = e.mutable_edit_result();
  r->set_request_id(request);
  r->set_status(status);
  r->set_reason(reason);
  reply(e);
}

void hello(const wire::Hello& h) {
  if (h.protocol_version() != net::kProtocolVersion) {
    error(wire::Error::BAD_VERSION,
          "protocol version " + std::to_string(h.protocol_version()) + " is not supported");
    return;
  }
  if (h.player_name().empty() || h.player_name().size() > 32) {
    error(wire::Error::BAD_VALUE, "player_name must be 1..32 bytes");
    return;
  }
  (void)net::escape_for_log(h.player_name());
}

void set_view(const wire::SetView& view) {
  const float p[3] = {view.position().x(), view.position().y(), view.position().z()};
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
    error(wire::Error::BAD_VALUE, "SetView position must be finite");
    return;
  }
  for (int a = 0; a < 3; ++a) {
    if (p[a] < static_cast<float>(kLimits.world_min[a]) ||
        p[a] > static_cast<float>(kLimits.world_max[a])) {
      error(wire::Error::BAD_VALUE, "SetView position is outside the world");
      return;
    }
  }
  if (view.radius() > kConfig.max_view_radius) {
    error(wire::Error::BAD_VALUE, "view radius " + std::to_string(view.radius()));
    return;
  }
  const world::ChunkCoord center = world::chunk_of_voxel(static_cast<int32_t>(std::floor(p[0])),
                                                         static_cast<int32_t>(std::floor(p[1])),
                                                         static_cast<int32_t>(std::floor(p[2])));
  (void)net::to_wire(center);
}

void resync(const wire::Resync& r) {
  if (static_cast<size_t>(r.coords_size()) > kConfig.max_resync_chunks) {
    error(wire::Error::BAD_VALUE, "Resync carries " + std::to_string(r.coords_size()));
    return;
  }
  for (const auto& c : r.coords()) (void)net::from_wire(c);
}

void edit(const wire::Edit& e) {
  net::WireEdit converted = net::edit_from_wire(e);
  if (!converted.edit) {
    check(converted.status != wire::EditResult::ACCEPTED);
    if (converted.unknown_enum) error(wire::Error::UNKNOWN_ENUM, converted.reason);
    result(e.request_id(), converted.status, converted.reason);
    return;
  }
  if (auto refusal = world::validate(*converted.edit, kLimits)) {
    check(refusal->reason != world::RefusalReason::kNone);
    result(e.request_id(), net::status_of(refusal->reason), refusal->message);
    return;
  }
  // A valid edit: its cost against the edit budget, and the chunks the pipeline loads.
  const world::VoxelBox box = world::touched_box(*converted.edit);
  double samples = 1;
  for (int a = 0; a < 3; ++a) {
    check(box.lo[a] <= box.hi[a]);
    check(box.lo[a] >= kLimits.world_min[a] && box.hi[a] <= kLimits.world_max[a]);
    samples *= static_cast<double>(box.hi[a]) - box.lo[a] + 1;
  }
  check(samples <= world::max_touched_samples(kLimits));  // voxeld's --edit-burst floor
  check(world::chunks_overlapping(box).size() <= 64);
}

// A RegionCommand as an admin's session takes it (region_commands.cpp): the region an
// add asks for, converted and validated as the pipeline does; when valid, what it holds
// back of an explosion over its corner stays within both boxes; the answer serialized.
void region_command(const wire::RegionCommand& c) {
  wire::Envelope e;
  auto* r = e.mutable_region_result();
  r->set_request_id(c.request_id());
  if (c.has_add()) {
    world::Region region = net::region_from_wire(c.add());
    region.id = 1;
    if (auto why = world::validate_region(region, kLimits, world::RegionLimits{})) {
      (void)net::escape_for_log(*why, 200);
      r->set_status(wire::RegionResult::BAD_VALUE);
    } else {
      const world::Edit boom = world::Explosion{
          {static_cast<float>(region.box.lo[0]), static_cast<float>(region.box.lo[1]),
           static_cast<float>(region.box.lo[2])},
          3,
          1};
      if (!world::validate(boom, kLimits)) {
        const world::Protection p = world::protection_for({&region, 1}, boom, "someone");
        for (const world::VoxelBox& k : p.keep) {
          check(world::box_contains(region.box, k));
          check(world::box_contains(world::touched_box(boom), k));
        }
      }
      *r->add_regions() = net::to_wire(region);
    }
  } else if (!c.has_list() && c.command_case() != wire::RegionCommand::kRemove) {
    r->set_status(wire::RegionResult::BAD_VALUE);
  }
  reply(e);
}

}  // namespace

// protobuf logs every string field of invalid UTF-8 it parses: noise here.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  wire::Envelope message;
  if (!message.ParseFromArray(data, static_cast<int>(size))) {
    error(wire::Error::MALFORMED, "the frame is not a valid Envelope");
    return 0;
  }
  if (net::has_unknown_fields(message)) {
    if (message.body_case() == wire::Envelope::kEdit) {
      result(message.edit().request_id(), wire::EditResult::BAD_VALUE, "unknown fields");
    }
    error(wire::Error::UNKNOWN_MESSAGE, "unknown fields");
    return 0;
  }
  switch (message.body_case()) {
    case wire::Envelope::kHello:
      hello(message.hello());
      break;
    case wire::Envelope::kSetView:
      set_view(message.set_view());
      break;
    case wire::Envelope::kEdit:
      edit(message.edit());
      break;
    case wire::Envelope::kResync:
      resync(message.resync());
      break;
    case wire::Envelope::kRegionCommand:
      region_command(message.region_command());
      break;
    case wire::Envelope::kPing: {
      wire::Envelope pong;
      pong.mutable_pong()->set_nonce(message.ping().nonce());
      reply(pong);
      break;
    }
    default:
      error(wire::Error::UNKNOWN_MESSAGE, "not a client message");
  }
  return 0;
}
