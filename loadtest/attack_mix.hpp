// --attack MIX: which hostile clients run beside the honest players, written as
// "kind:count,kind:count" (e.g. "flood:3,heavy:2,squat:2,slow:2,empty:1"). Pure parsing,
// no I/O, so every accepted and refused string is a unit test.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "proto/result.hpp"

namespace vox::loadtest {

enum class AttackKind : uint8_t {
  flood,  // far-apart SetViews of the largest radius every 20 ms; half reconnect every few s
  heavy,  // box stamps of the largest size, always max_edits_in_flight of them in flight
  squat,  // idle connections from one address: half never say Hello, half only ping
  slow,   // a view of the largest radius near the players, then never reads
  empty,  // empty frames (an empty Envelope each) as fast as the socket takes them
};
inline constexpr size_t kAttackKindCount = 5;
inline constexpr std::array<AttackKind, kAttackKindCount> kAttackKinds = {
    AttackKind::flood, AttackKind::heavy, AttackKind::squat, AttackKind::slow, AttackKind::empty};

const char* attack_kind_name(AttackKind kind);
std::optional<AttackKind> attack_kind_from_name(std::string_view name);

// Counts per kind are 0..this.
inline constexpr int kMaxAttackersPerKind = 1000;
// One squatter in the mix is a group of this many connections from 127.0.0.1 (the first
// half never send Hello, the second half do and then only ping): one idle socket is no
// attack, a few dozen per address is what a per-address cap has to stop.
inline constexpr int kSquatGroupSize = 32;

struct AttackMix {
  std::array<int, kAttackKindCount> counts{};

  int count(AttackKind kind) const { return counts[static_cast<size_t>(kind)]; }
  bool empty() const;
  // Connections the mix holds open at once (squatters: kSquatGroupSize per group).
  int connections() const;
  int connections(AttackKind kind) const;
  // Canonical text, kinds in enum order, zero counts left out ("" for no attack).
  std::string to_string() const;
};

// Parses MIX; the error names the offending part. Each kind at most once; an empty string,
// an empty part, a missing or non-decimal count or one over kMaxAttackersPerKind is refused.
proto::Result<AttackMix> parse_attack_mix(std::string_view text);

}  // namespace vox::loadtest
