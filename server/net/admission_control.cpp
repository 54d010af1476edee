#include "server/net/admission_control.hpp"

namespace vox::net {

AdmissionControl::Verdict AdmissionControl::connect(const std::string& address, bool capped) {
  if (handshaking_ >= limits_.max_handshaking) return Verdict::kHandshakesFull;
  auto it = per_address_.find(address);
  const Count from = it == per_address_.end() ? Count{} : it->second;
  if (capped && limits_.max_per_address != 0 && from.all >= limits_.max_per_address)
    return Verdict::kAddressFull;
  if (capped && limits_.max_handshaking_per_address != 0 &&
      from.handshaking >= limits_.max_handshaking_per_address)
    return Verdict::kAddressFull;
  Count& c = per_address_[address];
  ++c.all;
  ++c.handshaking;
  ++handshaking_;
  return Verdict::kAdmit;
}

AdmissionControl::Verdict AdmissionControl::promote(const std::string& address) {
  if (players_ >= limits_.max_players) return Verdict::kServerFull;
  --handshaking_;
  ++players_;
  --per_address_.at(address).handshaking;
  return Verdict::kAdmit;
}

void AdmissionControl::release(const std::string& address, bool was_player) {
  Count& c = per_address_.at(address);
  if (was_player) {
    --players_;
  } else {
    --handshaking_;
    --c.handshaking;
  }
  if (--c.all == 0) per_address_.erase(address);
}

size_t AdmissionControl::connections_from(const std::string& address) const {
  auto it = per_address_.find(address);
  return it == per_address_.end() ? 0 : it->second.all;
}

const char* to_string(AdmissionControl::Verdict v) {
  switch (v) {
    case AdmissionControl::Verdict::kAdmit:
      return "admitted";
    case AdmissionControl::Verdict::kHandshakesFull:
      return "too many connections in handshake";
    case AdmissionControl::Verdict::kAddressFull:
      return "too many connections from one address";
    case AdmissionControl::Verdict::kServerFull:
      return "server full";
  }
  return "?";
}

}  // namespace vox::net
