#include "server/net/edit_gate.hpp"

#include <algorithm>

#include "server/net/wire_convert.hpp"

namespace vox::net {

uint32_t clamp_ms(std::chrono::milliseconds ms) {
  return static_cast<uint32_t>(std::clamp<long long>(ms.count(), 0, UINT32_MAX));
}

double EditGate::cost(const world::Edit& edit) {
  const world::VoxelBox box = world::touched_box(edit);
  double samples = 1;
  for (int a = 0; a < 3; ++a) samples *= static_cast<double>(box.hi[a]) - box.lo[a] + 1;
  return samples;
}

std::optional<EditGate::Refusal> EditGate::admit(const world::Edit& edit, Clock::time_point now) {
  if (!budget_ || role_ == auth::Role::kViewer)
    return Refusal{wire::EditResult::FORBIDDEN, "a viewer may not edit"};
  if (auto refusal = world::validate(edit, limits_))
    return Refusal{status_of(refusal->reason), refusal->message};
  if (in_flight_ >= max_in_flight_) {
    // A client cannot queue unbounded work in the shared pipeline.
    return Refusal{wire::EditResult::TOO_MANY_EDITS,
                   "over " + std::to_string(max_in_flight_) + " edits still being applied"};
  }
  const double samples = cost(edit);
  if (const auto wait = budget_->take(samples, now); wait.count() > 0) {
    return Refusal{
        wire::EditResult::RATE_LIMITED,
        "over the edit budget (" + std::to_string(static_cast<uint64_t>(samples)) + " samples)",
        clamp_ms(wait)};
  }
  ++in_flight_;
  return std::nullopt;
}

void EditGate::answered(size_t work_chunks, Clock::time_point now) {
  --in_flight_;
  if (work_chunks > 0) budget_->charge(static_cast<double>(work_chunks) * kSamplesPerChunk, now);
}

uint32_t EditGate::rate_limited_retry_ms(Clock::time_point now) const {
  return clamp_ms(budget_->wait_for(kSamplesPerChunk, now));
}

}  // namespace vox::net
