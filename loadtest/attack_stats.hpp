// What the hostile clients of --attack did and what the server did to them: counted
// apart from the honest players, never part of the honest figures or the exit code.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <mutex>
#include <string>

#include "loadtest/attack_mix.hpp"

namespace vox::loadtest {

struct AttackKindStats {
  int clients = 0;      // from the mix (a squatter is a group of kSquatGroupSize)
  int connections = 0;  // sockets of this kind open at once at most
  uint64_t connects = 0, connect_failures = 0, welcomed = 0;
  uint64_t disconnects = 0;  // connections the server closed (or reset) under the attacker
  uint64_t messages_sent = 0, sends_dropped = 0, messages_received = 0, bytes_received = 0;
  uint64_t edits_sent = 0;
  std::map<std::string, uint64_t> errors;        // Error messages received, by code name
  std::map<std::string, uint64_t> edit_results;  // EditResults received, by status name
};

struct AttackStats {
  std::string mix;  // canonical MIX text; empty: no attack
  std::array<AttackKindStats, kAttackKindCount> kinds{};
  std::map<std::string, double> server_limits;  // from the first Welcome an attacker got
};

// Thread-safe tallies the attackers write from any event-loop thread. Counters are
// relaxed atomics (heavy editors and empty-frame senders count tens of thousands a
// second); codes and statuses are small enums, so they are atomics indexed by value too.
class AttackTally {
 public:
  enum Counter : uint8_t {
    kConnects,
    kConnectFailures,
    kWelcomed,
    kDisconnects,
    kMessagesSent,
    kSendsDropped,
    kMessagesReceived,
    kBytesReceived,
    kEditsSent,
    kCounterCount
  };
  // Codes and statuses at or over this share the last slot ("other").
  static constexpr size_t kCodeSlots = 32;

  void count(AttackKind kind, Counter counter, uint64_t n = 1);  // any thread
  void error(AttackKind kind, int code);                         // any thread
  void edit_result(AttackKind kind, int status);                 // any thread
  // The first call wins; later ones are ignored (any thread).
  void set_server_limits(std::map<std::string, double> limits);
  AttackStats snapshot(const AttackMix& mix) const;  // any thread

 private:
  struct PerKind {
    std::array<std::atomic<uint64_t>, kCounterCount> counters{};
    std::array<std::atomic<uint64_t>, kCodeSlots> errors{}, results{};
  };
  std::array<PerKind, kAttackKindCount> kinds_;
  mutable std::mutex limits_mutex_;  // a leaf: guards limits_ only
  std::map<std::string, double> limits_;
};

// A few lines under the honest table, one object for the JSON report.
void write_attack_table(const AttackStats& s, std::ostream& out);
void write_attack_json(const AttackStats& s, std::ostream& out);

}  // namespace vox::loadtest
