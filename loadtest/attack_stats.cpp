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
  for (AttackKind kind : kAttackKinds) {
    const AttackKindStats& k = s.kinds[static_cast<size_t>(kind)];
    if (k.clients == 0) continue;
    char name[16];
    std::snprintf(name, sizeof name, "%-5s", attack_kind_name(kind));
    out << "  " << name << " x" << k.clients << " (" << k.connections << " sockets): " << k.connects
        << " connections (" << k.connect_failures << " failed, " << k.welcomed << " welcomed), "
        << k.disconnects << " closed by the server, " << k.messages_sent << " messages sent ("
        << k.sends_dropped << " dropped: socket full), " << k.messages_received << " received\n";
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
    out << (first ? "" : ",") << "\"" << attack_kind_name(kind) << "\":{\"clients\":" << k.clients
        << ",\"sockets\":" << k.connections;
    const std::pair<const char*, uint64_t> counters[] = {{"connects", k.connects},
                                                         {"connect_failures", k.connect_failures},
                                                         {"welcomed", k.welcomed},
                                                         {"disconnects", k.disconnects},
                                                         {"messages_sent", k.messages_sent},
                                                         {"sends_dropped", k.sends_dropped},
                                                         {"messages_received", k.messages_received},
                                                         {"bytes_received", k.bytes_received},
                                                         {"edits_sent", k.edits_sent}};
    for (const auto& [key, value] : counters) out << ",\"" << key << "\":" << value;
    out << ",";
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
