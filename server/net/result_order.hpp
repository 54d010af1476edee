// Keeps one client's EditResults in the order of its Edits: a result decided at once (a
// refusal by the session) waits behind the results of earlier edits still in the
// pipeline. It also says which mesh versions may not be sent yet: an edit's result must
// reach the client before the meshes showing the edit (docs/PROTOCOL.md section 4.7), so
// while an edit is in the pipeline, no version it may have made goes out. Pure; one
// owner (the session's strand).
#pragma once

#include <cstdint>
#include <deque>
#include <limits>
#include <optional>

#include "voxel.pb.h"

namespace vox::net {

class ResultOrder {
 public:
  static constexpr uint64_t kNoLimit = std::numeric_limits<uint64_t>::max();

  // A slot for an edit handed to the pipeline; fill() it with the result later.
  // `first_version`: no version the edit makes is below it (the newest published version
  // + 1, read before the edit was submitted).
  uint64_t reserve(uint64_t first_version = 0) {
    slots_.push_back({std::nullopt, first_version});
    return first_ticket_ + slots_.size() - 1;
  }
  // A result known now: it follows every earlier edit's.
  void push_ready(wire::Envelope result) { slots_.push_back({std::move(result), kNoLimit}); }
  void fill(uint64_t ticket, wire::Envelope result) {
    slots_[static_cast<size_t>(ticket - first_ticket_)].result = std::move(result);
  }
  // The results that may be sent now, in order.
  template <class Out>
  void drain(Out&& out) {
    while (!slots_.empty() && slots_.front().result) {
      out(*slots_.front().result);
      slots_.pop_front();
      ++first_ticket_;
    }
  }
  size_t size() const { return slots_.size(); }
  // Mesh versions at or above this may show an edit whose result has not been drained.
  // After drain() the front slot, if any, is an edit still in the pipeline, and the
  // oldest such edit has the lowest first version.
  uint64_t first_unsendable_version() const {
    return slots_.empty() ? kNoLimit : slots_.front().first_version;
  }

 private:
  struct Slot {
    std::optional<wire::Envelope> result;
    uint64_t first_version;
  };
  std::deque<Slot> slots_;
  uint64_t first_ticket_ = 0;  // ticket of slots_.front()
};

}  // namespace vox::net
