#include "loadtest/attack_stats.hpp"

#include <algorithm>
#include <cstdio>
#include <ostream>

#include "voxel.pb.h"

namespace vox::loadtest {

namespace {

size_t slot(int value) {
  return static_cast<size_t>(std::clamp<int>(value, 0, AttackTally::kCodeSlots - 1));
}

std::string error_name(size_t code) {
  const auto& name = wire::Error::Code_Name(static_cast<int>(code));
  return name.empty() ? "code " + std::to_string(code) : name;
}

std::string status_name(size_t status) {
  const auto& name = wire::EditResult::Status_Name(static_cast<int>(status));
  return name.empty() ? "status " + std::to_string(status) : name;
}

std::string joined(const std::map<std::string, uint64_t>& m) {
  std::string out;
  for (const auto& [k, v] : m) out += (out.empty() ? "" : ", ") + k + " " + std::to_string(v);
  return out.empty() ? "none" : out;
}

void json_counts(std::ostream& out, const char* name, const std::map<std::string, uint64_t>& m) {
  out << "\"" << name << "\":{";
  bool first = true;
  for (const auto& [k, v] : m) {
    out << (first ? "" : ",") << "\"" << k << "\":" << v;
    first = false;
  }
  out << "}";
}

}  // namespace

void AttackTally::count(AttackKind kind, Counter counter, uint64_t n) {
  kinds_[static_cast<size_t>(kind)].counters[counter].fetch_add(n, std::memory_order_relaxed);
}

void AttackTally::error(AttackKind kind, int code) {
  kinds_[static_cast<size_t>(kind)].errors[slot(code)].fetch_add(1, std::memory_order_relaxed);
}

void AttackTally::edit_result(AttackKind kind, int status) {
  kinds_[static_cast<size_t>(kind)].results[slot(status)].fetch_add(1, std::memory_order_relaxed);
}

void AttackTally::set_server_limits(std::map<std::string, double> limits) {
  std::lock_guard lock(limits_mutex_);
  if (limits_.empty()) limits_ = std::move(limits);
}

AttackStats AttackTally::snapshot(const AttackMix& mix) const {
  AttackStats s;
  s.mix = mix.to_string();
  {
    std::lock_guard lock(limits_mutex_);
    s.server_limits = limits_;
  }
  for (AttackKind kind : kAttackKinds) {
    const PerKind& k = kinds_[static_cast<size_t>(kind)];
    AttackKindStats& o = s.kinds[static_cast<size_t>(kind)];
    auto get = [&k](Counter c) { return k.counters[c].load(std::memory_order_relaxed); };
    o.clients = mix.count(kind);
    o.connections = mix.connections(kind);
    o.connects = get(kConnects);
    o.connect_failures = get(kConnectFailures);
    o.welcomed = get(kWelcomed);
    o.disconnects = get(kDisconnects);
    o.messages_sent = get(kMessagesSent);
    o.sends_dropped = get(kSendsDropped);
    o.messages_received = get(kMessagesReceived);
    o.bytes_received = get(kBytesReceived);
    o.edits_sent = get(kEditsSent);
    for (size_t i = 0; i < kCodeSlots; ++i) {
      if (const auto n = k.errors[i].load(std::memory_order_relaxed)) o.errors[error_name(i)] = n;
      if (const auto n = k.results[i].load(std::memory_order_relaxed))
        o.edit_results[status_name(i)] = n;
    }
  }
  return s;
}

void write_attack_table(const AttackStats& s, std::ostream& out) {
  if (s.mix.empty()) return;
  out << "attackers (" << s.mix << "; not part of the figures above)\n";
  char buf[512];
  for (AttackKind kind : kAttackKinds) {
    const AttackKindStats& k = s.kinds[static_cast<size_t>(kind)];
    if (k.clients == 0) continue;
    std::snprintf(buf, sizeof buf,
                  "  %-5s x%d (%d sockets): %llu connections (%llu failed, %llu welcomed), %llu "
                  "closed by the server, %llu messages sent (%llu dropped: socket full), %llu "
                  "received\n",
                  attack_kind_name(kind), k.clients, k.connections,
                  static_cast<unsigned long long>(k.connects),
                  static_cast<unsigned long long>(k.connect_failures),
                  static_cast<unsigned long long>(k.welcomed),
                  static_cast<unsigned long long>(k.disconnects),
                  static_cast<unsigned long long>(k.messages_sent),
                  static_cast<unsigned long long>(k.sends_dropped),
                  static_cast<unsigned long long>(k.messages_received));
    out << buf;
    if (!k.errors.empty()) out << "        errors from the server: " << joined(k.errors) << "\n";
    if (k.edits_sent > 0) {
      out << "        edits sent " << k.edits_sent << ", results: " << joined(k.edit_results)
          << "\n";
    }
  }
  if (!s.server_limits.empty()) {
    out << "  server limits (Welcome):";
    for (const auto& [k, v] : s.server_limits) out << " " << k << " " << v;
    out << "\n";
  }
}

void write_attack_json(const AttackStats& s, std::ostream& out) {
  out << "\"attackers\":{\"mix\":\"" << s.mix << "\",\"kinds\":{";
  bool first = true;
  for (AttackKind kind : kAttackKinds) {
    const AttackKindStats& k = s.kinds[static_cast<size_t>(kind)];
    if (k.clients == 0) continue;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "%s\"%s\":{\"clients\":%d,\"sockets\":%d,\"connects\":%llu,\"connect_failures\":"
                  "%llu,\"welcomed\":%llu,\"disconnects\":%llu,\"messages_sent\":%llu,\"sends_"
                  "dropped\":%llu,\"messages_received\":%llu,\"bytes_received\":%llu,\"edits_"
                  "sent\":%llu,",
                  first ? "" : ",", attack_kind_name(kind), k.clients, k.connections,
                  static_cast<unsigned long long>(k.connects),
                  static_cast<unsigned long long>(k.connect_failures),
                  static_cast<unsigned long long>(k.welcomed),
                  static_cast<unsigned long long>(k.disconnects),
                  static_cast<unsigned long long>(k.messages_sent),
                  static_cast<unsigned long long>(k.sends_dropped),
                  static_cast<unsigned long long>(k.messages_received),
                  static_cast<unsigned long long>(k.bytes_received),
                  static_cast<unsigned long long>(k.edits_sent));
    out << buf;
    json_counts(out, "errors_by_code", k.errors);
    out << ",";
    json_counts(out, "edit_results_by_status", k.edit_results);
    out << "}";
    first = false;
  }
  out << "},\"server_limits\":{";
  first = true;
  for (const auto& [k, v] : s.server_limits) {
    out << (first ? "" : ",") << "\"" << k << "\":" << v;
    first = false;
  }
  out << "}}";
}

}  // namespace vox::loadtest
