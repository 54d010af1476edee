#include "net/admission_control.hpp"

namespace vox::net {

AdmissionControl::Verdict AdmissionControl::connect(const std::string& address) {
  if (handshaking_ >= limits_.max_handshaking) return Verdict::kHandshakesFull;
  size_t& from = per_address_[address];
  if (limits_.max_per_address != 0 && from >= limits_.max_per_address) {
    if (from == 0) per_address_.erase(address);
    return Verdict::kAddressFull;
  }
  ++from;
  ++handshaking_;
  return Verdict::kAdmit;
}

AdmissionControl::Verdict AdmissionControl::promote() {
  if (players_ >= limits_.max_players) return Verdict::kServerFull;
  --handshaking_;
  ++players_;
  return Verdict::kAdmit;
}

void AdmissionControl::release(const std::string& address, bool was_player) {
  if (was_player) {
    --players_;
  } else {
    --handshaking_;
  }
  auto it = per_address_.find(address);
  if (it != per_address_.end() && --it->second == 0) per_address_.erase(it);
}

size_t AdmissionControl::connections_from(const std::string& address) const {
  auto it = per_address_.find(address);
  return it == per_address_.end() ? 0 : it->second;
}

const char* to_string(AdmissionControl::Verdict v) {
  switch (v) {
    case AdmissionControl::Verdict::kAdmit: return "admitted";
    case AdmissionControl::Verdict::kHandshakesFull: return "too many connections in handshake";
    case AdmissionControl::Verdict::kAddressFull: return "too many connections from one address";
    case AdmissionControl::Verdict::kServerFull: return "server full";
  }
  return "?";
}

}  // namespace vox::net
