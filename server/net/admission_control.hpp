// Who may connect and who may become a player. Pure bookkeeping (no I/O, no threads); the
// server calls it under one leaf mutex, tests call it directly.
//
// - A connection that has not finished Hello does not count against the player cap; the
//   handshaking ones have their own small cap (and the handshake timeout).
// - Each address may hold at most `max_per_address` connections (players and
//   handshaking together), so one address cannot fill the server, and at most
//   `max_handshaking_per_address` of them before Hello, so a few addresses cannot hold
//   every handshake slot.
// - A Hello beyond `max_players` players is refused (SERVER_FULL).
#pragma once

#include <cstddef>
#include <mutex>
#include <string>
#include <unordered_map>

namespace vox::net {

struct AdmissionLimits {
  size_t max_players = 256;
  size_t max_handshaking = 64;
  size_t max_per_address = 16;             // 0: no cap
  size_t max_handshaking_per_address = 4;  // 0: no cap
};

class AdmissionControl {
 public:
  enum class Verdict { kAdmit, kHandshakesFull, kAddressFull, kServerFull };

  explicit AdmissionControl(AdmissionLimits limits) : limits_(limits) {}
  const AdmissionLimits& limits() const { return limits_; }
  // New caps (a reload): connections over them stay; new ones are refused until under.
  void set_limits(AdmissionLimits limits) { limits_ = limits; }

  // A new connection from `address`; on kAdmit it counts as handshaking until promote()
  // or release(). Not `capped`: only the totals apply (a trusted proxy's connections, each
  // a different client).
  Verdict connect(const std::string& address, bool capped = true);
  // Its Hello arrived: kAdmit makes it a player; kServerFull leaves it handshaking (the
  // caller closes it and calls release).
  Verdict promote(const std::string& address);
  // The connection closed; `was_player` as promote() left it.
  void release(const std::string& address, bool was_player);

  size_t players() const { return players_; }
  size_t handshaking() const { return handshaking_; }
  size_t connections_from(const std::string& address) const;

 private:
  AdmissionLimits limits_;
  size_t players_ = 0, handshaking_ = 0;
  struct Count {
    size_t all = 0, handshaking = 0;
  };
  std::unordered_map<std::string, Count> per_address_;  // only addresses with connections
};

const char* to_string(AdmissionControl::Verdict v);

// AdmissionControl behind a leaf mutex: the accept chain and every session use it. Any
// thread.
class AdmissionGate {
 public:
  explicit AdmissionGate(AdmissionLimits limits) : control_(limits) {}
  AdmissionControl::Verdict connect(const std::string& address, bool capped = true) {
    std::lock_guard lock(mutex_);
    return control_.connect(address, capped);
  }
  AdmissionControl::Verdict promote(const std::string& address) {
    std::lock_guard lock(mutex_);
    return control_.promote(address);
  }
  void release(const std::string& address, bool was_player) {
    std::lock_guard lock(mutex_);
    control_.release(address, was_player);
  }
  AdmissionLimits limits() const {
    std::lock_guard lock(mutex_);
    return control_.limits();
  }
  void set_limits(AdmissionLimits limits) {
    std::lock_guard lock(mutex_);
    control_.set_limits(limits);
  }

 private:
  mutable std::mutex mutex_;  // leaf lock
  AdmissionControl control_;
};

}  // namespace vox::net
