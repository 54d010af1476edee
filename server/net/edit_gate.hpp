// Whether a player's edit goes to the pipeline or is refused at once, and what it costs:
// the player's role (a viewer never edits), the edit's values (world::validate), a cap on
// its edits in the pipeline at once, and its edit budget (samples its box touches, shared
// by the player's connections). Terrain an edit made the server generate, and uniform
// chunks it made full, are charged after its answer, as debt: an edit where nothing is
// loaded costs far more than its samples. Pure but for the clock it is given; the
// session's strand only.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "server/auth/player_token.hpp"
#include "server/net/edit_budget.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "voxel.pb.h"

namespace vox::net {

class EditGate {
 public:
  using Clock = std::chrono::steady_clock;

  EditGate(world::EditLimits limits, size_t max_in_flight)
      : limits_(limits), max_in_flight_(max_in_flight) {}

  // At Hello: the player's role and its budget (the player's shared one, or the
  // session's own on an open server). Until then every edit is refused.
  void join(auth::Role role, std::shared_ptr<SharedEditBudget> budget) {
    role_ = role;
    budget_ = std::move(budget);
  }
  const SharedEditBudget* budget() const { return budget_.get(); }
  // A reload's new limits (the tokens held are kept, up to the new burst); nothing before
  // Hello.
  void set_budget_limits(BudgetLimits l, Clock::time_point now) {
    if (budget_) budget_->set_limits(l, now);
  }

  struct Refusal {
    wire::EditResult::Status status;
    std::string reason;
    uint32_t retry_after_ms = 0;
  };
  // Admits the edit (then it counts in flight until answered()) or says why not.
  std::optional<Refusal> admit(const world::Edit& edit, Clock::time_point now);
  // The pipeline answered an admitted edit, having generated (or made full) `work_chunks`
  // chunks for it.
  void answered(size_t work_chunks, Clock::time_point now);
  // The retry hint of an edit the pipeline answered RATE_LIMITED: until a chunk's worth.
  uint32_t rate_limited_retry_ms(Clock::time_point now) const;
  size_t in_flight() const { return in_flight_; }

  // Samples an edit's box touches: its cost against the budget.
  static double cost(const world::Edit& edit);
  // What generating one chunk of terrain (or making a uniform one full) costs: its samples.
  static constexpr double kSamplesPerChunk = world::kChunkVolume;

 private:
  const world::EditLimits limits_;
  const size_t max_in_flight_;
  auth::Role role_ = auth::Role::kViewer;
  std::shared_ptr<SharedEditBudget> budget_;
  size_t in_flight_ = 0;  // admitted, not answered yet
};

// A wire duration of at most UINT32_MAX milliseconds.
uint32_t clamp_ms(std::chrono::milliseconds ms);

}  // namespace vox::net
