// Keeps one client's EditResults in the order of its Edits: a result decided at once (a
// refusal by the session) waits behind the results of earlier edits still in the
// pipeline. Pure; one owner (the session's strand).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>

#include "voxel.pb.h"

namespace vox::net {

class ResultOrder {
 public:
  // A slot for an edit handed to the pipeline; fill() it with the result later.
  uint64_t reserve() {
    slots_.emplace_back();
    return first_ticket_ + slots_.size() - 1;
  }
  // A result known now: it follows every earlier edit's.
  void push_ready(wire::Envelope result) { slots_.emplace_back(std::move(result)); }
  void fill(uint64_t ticket, wire::Envelope result) {
    slots_[static_cast<size_t>(ticket - first_ticket_)] = std::move(result);
  }
  // The results that may be sent now, in order.
  template <class Out>
  void drain(Out&& out) {
    while (!slots_.empty() && slots_.front()) {
      out(*slots_.front());
      slots_.pop_front();
      ++first_ticket_;
    }
  }
  size_t size() const { return slots_.size(); }

 private:
  std::deque<std::optional<wire::Envelope>> slots_;
  uint64_t first_ticket_ = 0;  // ticket of slots_.front()
};

}  // namespace vox::net
