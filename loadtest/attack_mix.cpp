#include "loadtest/attack_mix.hpp"

namespace vox::loadtest {

namespace {
constexpr std::array<const char*, kAttackKindCount> kNames = {"flood", "heavy", "squat", "slow",
                                                              "empty"};

std::string known_kinds() {
  std::string out;
  for (const char* n : kNames) {
    if (!out.empty()) out += ", ";
    out += n;
  }
  return out;
}

// A decimal count 0..kMaxAttackersPerKind: digits only (no sign, no spaces, no "0x").
std::optional<int> parse_count(std::string_view text) {
  if (text.empty() || text.size() > 4) return std::nullopt;
  int value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return std::nullopt;
    value = value * 10 + (c - '0');
  }
  if (value > kMaxAttackersPerKind) return std::nullopt;
  return value;
}
// 'text' (built by appending: GCC 12 warns falsely about "'" + std::string).
std::string quoted(std::string_view text) {
  std::string out;
  out.reserve(text.size() + 2);
  out += '\'';
  out.append(text);
  out += '\'';
  return out;
}
}  // namespace

const char* attack_kind_name(AttackKind kind) { return kNames[static_cast<size_t>(kind)]; }

std::optional<AttackKind> attack_kind_from_name(std::string_view name) {
  for (AttackKind k : kAttackKinds) {
    if (name == attack_kind_name(k)) return k;
  }
  return std::nullopt;
}

bool AttackMix::empty() const {
  for (int c : counts) {
    if (c > 0) return false;
  }
  return true;
}

int AttackMix::connections(AttackKind kind) const {
  return count(kind) * (kind == AttackKind::squat ? kSquatGroupSize : 1);
}

int AttackMix::connections() const {
  int n = 0;
  for (AttackKind k : kAttackKinds) n += connections(k);
  return n;
}

std::string AttackMix::to_string() const {
  std::string out;
  for (AttackKind k : kAttackKinds) {
    if (count(k) == 0) continue;
    if (!out.empty()) out += ',';
    out += attack_kind_name(k);
    out += ':';
    out += std::to_string(count(k));
  }
  return out;
}

proto::Result<AttackMix> parse_attack_mix(std::string_view text) {
  if (text.empty()) return proto::Error{"the attack mix is empty (e.g. flood:2,heavy:1)"};
  AttackMix mix;
  std::array<bool, kAttackKindCount> seen{};
  while (true) {
    const size_t comma = text.find(',');
    const std::string_view part = text.substr(0, comma);
    const size_t colon = part.find(':');
    if (part.empty()) return proto::Error{"an empty part in the attack mix"};
    if (colon == std::string_view::npos) return proto::Error{quoted(part) + " is not KIND:COUNT"};
    const auto kind = attack_kind_from_name(part.substr(0, colon));
    if (!kind) {
      return proto::Error{"unknown attacker kind " + quoted(part.substr(0, colon)) +
                          " (kinds: " + known_kinds() + ")"};
    }
    const auto count = parse_count(part.substr(colon + 1));
    if (!count) {
      return proto::Error{"the count in " + quoted(part) + " is not a number 0.." +
                          std::to_string(kMaxAttackersPerKind)};
    }
    auto& was_seen = seen[static_cast<size_t>(*kind)];
    if (was_seen) return proto::Error{quoted(attack_kind_name(*kind)) + " is given twice"};
    was_seen = true;
    mix.counts[static_cast<size_t>(*kind)] = *count;
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  return mix;
}

}  // namespace vox::loadtest
