// The session's protected-region commands (docs/PROTOCOL.md 4.9): add, remove and list,
// for admins only. Changes go through the pipeline, in order with edits, and are answered
// once durable; a list reads the regions in force. Strand only, but where a comment says
// otherwise.
#include <spdlog/spdlog.h>

#include "server/net/client_session.hpp"
#include "server/net/wire_convert.hpp"

namespace vox::net {

namespace {

// A list answer stops near this size (the rest in further pages), far below the
// control-queue bound, whatever the regions hold.
constexpr size_t kListPageBytes = 32 * 1024;

std::string describe_region(const world::Region& r) {
  const char* flags = r.flags == world::kRegionFlagsKnown ? "build+explode"
                      : (r.flags & world::kProtectBuild)  ? "build"
                                                          : "explode";
  return fmt::format("{} '{}' ({}, {}, {})..({}, {}, {}) {} with {} owners", r.id,
                     escape_for_log(r.name), r.box.lo[0], r.box.lo[1], r.box.lo[2], r.box.hi[0],
                     r.box.hi[1], r.box.hi[2], flags, r.owners.size());
}

}  // namespace

void ClientSession::handle_region_command(const wire::RegionCommand& command) {
  wire::Envelope reply;
  auto* result = reply.mutable_region_result();
  result->set_request_id(command.request_id());
  auto refuse = [&](wire::RegionResult::Status status, const std::string& reason) {
    result->set_status(status);
    result->set_reason(reason);
    queue_control(reply);
  };
  if (role_ != auth::Role::kAdmin) {
    if (auto suppressed = services_.logs->allow("region-refused", 5)) {
      spdlog::warn("session {}: player '{}' ({}, {}) may not manage protected regions{}", id_,
                   log_name_, player_id_.empty() ? "no id" : escape_for_log(player_id_),
                   auth::to_string(role_),
                   *suppressed ? fmt::format(" [{} more refused]", *suppressed) : std::string());
    }
    return refuse(wire::RegionResult::FORBIDDEN, "only an admin may manage protected regions");
  }
  switch (command.command_case()) {
    case wire::RegionCommand::kList:
      return list_regions(command.list().after_id(), reply);
    case wire::RegionCommand::kAdd:
    case wire::RegionCommand::kRemove:
      break;
    default:
      return refuse(wire::RegionResult::BAD_VALUE, "the RegionCommand carries no command");
  }
  if (region_commands_in_flight_ >= kMaxRegionCommandsInFlight) {
    return refuse(wire::RegionResult::BAD_VALUE, "over " +
                                                     std::to_string(kMaxRegionCommandsInFlight) +
                                                     " region commands still being applied");
  }
  pipeline::RegionTask task;
  if (command.has_add()) {
    task.add = region_from_wire(command.add());
    task.add->created_by = player_id_;
    task.add->created_unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                    .count();
  } else {
    task.remove_id = command.remove();
  }
  task.by = player_id_;
  ++region_commands_in_flight_;
  task.done = [self = shared_from_this(), reply,
               adding = command.has_add()](const pipeline::RegionOutcome& outcome) mutable {
    // Pipeline thread: build the answer here, queue it on the strand.
    auto* r = reply.mutable_region_result();
    r->set_status(status_of(outcome.status));
    r->set_reason(outcome.message);
    if (outcome.status == pipeline::RegionOutcome::Status::kOk)
      *r->add_regions() = to_wire(outcome.region);
    std::string line =
        outcome.status == pipeline::RegionOutcome::Status::kOk
            ? fmt::format("{} protected region {}", adding ? "added" : "removed",
                          describe_region(outcome.region))
            : fmt::format("{} a protected region refused: {}", adding ? "adding" : "removing",
                          escape_for_log(outcome.message, 200));
    asio::post(self->strand_, [self, reply = std::move(reply), line = std::move(line)] {
      --self->region_commands_in_flight_;
      if (auto suppressed = self->services_.logs->allow("region", 20)) {
        spdlog::info(
            "session {}: admin '{}' ({}) {}{}", self->id_, self->log_name_,
            self->player_id_.empty() ? "no id" : escape_for_log(self->player_id_), line,
            *suppressed ? fmt::format(" [{} more region changes]", *suppressed) : std::string());
      }
      self->queue_control(reply);
    });
  };
  pipeline_.change_regions(std::move(task));
}

// One page of the regions in force with ids above `after_id`.
void ClientSession::list_regions(uint64_t after_id, wire::Envelope& reply) {
  auto* result = reply.mutable_region_result();
  const auto regions = pipeline_.regions();
  auto it = std::upper_bound(regions->begin(), regions->end(), after_id,
                             [](uint64_t id, const world::Region& r) { return id < r.id; });
  size_t bytes = 0;
  for (; it != regions->end() && bytes < kListPageBytes; ++it) {
    *result->add_regions() = to_wire(*it);
    bytes += result->regions(result->regions_size() - 1).ByteSizeLong();
  }
  result->set_more(it != regions->end());
  result->set_status(wire::RegionResult::OK);
  queue_control(reply);
}

}  // namespace vox::net
