// What the load test measures, and its reports: a human-readable table and JSON (over time:
// loadtest/timeline.hpp; the SVG charts: loadtest/report_svg.hpp). Every figure but `attack` and
// the server's RSS is the honest players' alone.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <map>
#include <string>
#include <vector>

#include "loadtest/attack_stats.hpp"

namespace vox::loadtest {

struct Percentiles {
  double p50 = 0, p95 = 0, p99 = 0, p999 = 0, max = 0;
  size_t count = 0;
};
// Nearest rank: pXX is the smallest sample that at least XX % of them do not exceed. No
// samples: every figure 0 and count 0.
Percentiles percentiles(std::vector<double> values);

struct LatencySample {
  double at_s;  // since the test started
  double ms;
};

struct LoadStats {
  int players = 0;
  double duration_s = 0;  // the measured (editing) part
  uint64_t edits_sent = 0, results = 0, refused = 0;
  std::map<std::string, uint64_t> refused_by_status;  // EditResult status name -> count
  uint64_t messages_received = 0, bytes_received = 0, chunks_streamed = 0;
  uint64_t decode_failures = 0;
  int players_connected = 0;
  std::vector<LatencySample> edit_to_result, edit_to_delta;
  std::vector<double> first_view_ms;
  // --reconnect: connection closed -> Welcome from the next server, and -> its first view
  // complete; unanswered edits sent again, and of them answered already_applied.
  std::vector<double> reconnect_ms, reconnect_view_ms;
  uint64_t edits_resent = 0, resent_already_applied = 0;
  std::map<std::string, uint64_t> errors;       // by cause (Error code name, decode failure, ...)
  std::map<std::string, uint64_t> disconnects;  // by cause
  std::vector<double> bytes_per_second;         // received by all players, per second of the test
  uint64_t verify_mismatches = 0;
  bool verified = false;
  AttackStats attack;                      // the hostile clients (--attack); mix empty: none
  int server_pid = 0;                      // whose RSS was sampled; 0: none
  std::vector<double> server_rss_kib;      // voxeld's VmRSS, one sample a second from the start
  std::vector<double> server_cpu_percent;  // voxeld's CPU in each second, % of one core
  std::vector<double> tester_cpu_percent;  // this load tester's, the same way
  std::vector<double> host_steal_percent;  // stolen by the hypervisor, % of one core

  uint64_t error_count() const;
  uint64_t disconnect_count() const;
};

void write_table(const LoadStats& s, std::ostream& out);
void write_json(const LoadStats& s, std::ostream& out);
// The SVG reports are in loadtest/report_svg.hpp.

}  // namespace vox::loadtest
