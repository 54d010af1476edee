#include "loadtest/load_stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>

#include "loadtest/timeline.hpp"

namespace vox::loadtest {

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.count = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  // Nearest rank: the smallest sample that at least q of them do not exceed, rank
  // ceil(q * n), in integers (q * n in floating point can land just above a whole number).
  auto at = [&v](size_t per_10k) { return v[(per_10k * v.size() + 9999) / 10000 - 1]; };
  p.p50 = at(5000);
  p.p95 = at(9500);
  p.p99 = at(9900);
  p.p999 = at(9990);
  p.max = v.back();
  return p;
}

namespace {

std::vector<double> values(const std::vector<LatencySample>& samples) {
  std::vector<double> v;
  v.reserve(samples.size());
  for (const auto& s : samples) v.push_back(s.ms);
  return v;
}

uint64_t total(const std::map<std::string, uint64_t>& m) {
  uint64_t n = 0;
  for (const auto& [k, v] : m) n += v;
  return n;
}

void json_percentiles(std::ostream& out, const char* name, const Percentiles& p) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "\"%s\":{\"p50\":%.3f,\"p95\":%.3f,\"p99\":%.3f,\"p999\":%.3f,\"max\":%.3f,"
                "\"count\":%zu}",
                name, p.p50, p.p95, p.p99, p.p999, p.max, p.count);
  out << buf;
}

void json_map(std::ostream& out, const char* key, const std::map<std::string, uint64_t>& m) {
  out << "\"" << key << "\":{";
  bool first = true;
  for (const auto& [k, v] : m) {
    out << (first ? "" : ",") << "\"" << k << "\":" << v;
    first = false;
  }
  out << "}";
}

// "server_rss": the sampled pid, max and final KiB, and every sample (one a second).
void write_rss_json(const LoadStats& s, std::ostream& out) {
  if (s.server_rss_kib.empty()) return;
  auto kib = [](double v) { return static_cast<unsigned long long>(v); };
  out << ",\"server_rss\":{\"pid\":" << s.server_pid
      << ",\"max_kib\":" << kib(*std::max_element(s.server_rss_kib.begin(), s.server_rss_kib.end()))
      << ",\"final_kib\":" << kib(s.server_rss_kib.back()) << ",\"per_second_kib\":[";
  for (size_t i = 0; i < s.server_rss_kib.size(); ++i)
    out << (i ? "," : "") << kib(s.server_rss_kib[i]);
  out << "]}";
}

// "%.1f", or null when the figure was not sampled.
std::string optional_json(const std::optional<double>& v) {
  if (!v) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", *v);
  return buf;
}

// Over time: per second and per minute of the run, edit -> delta percentiles, bytes
// received and voxeld's RSS and CPU; the worst second.
void write_timeline_json(const Timeline& t, std::ostream& out) {
  char buf[320];
  out << ",\"per_second\":[";
  for (size_t i = 0; i < t.seconds.size(); ++i) {
    const SecondStats& s = t.seconds[i];
    std::snprintf(buf, sizeof buf,
                  "%s{\"t\":%zu,\"deltas\":%zu,\"p50_ms\":%.3f,\"p99_ms\":%.3f,\"p999_ms\":%.3f,"
                  "\"max_ms\":%.3f,\"bytes\":%.0f,",
                  i ? "," : "", i, s.delta.count, s.delta.p50, s.delta.p99, s.delta.p999,
                  s.delta.max, s.bytes);
    out << buf << "\"rss_mib\":" << optional_json(s.rss_mib)
        << ",\"cpu_percent\":" << optional_json(s.cpu_percent)
        << ",\"tester_cpu_percent\":" << optional_json(s.tester_cpu_percent)
        << ",\"steal_percent\":" << optional_json(s.steal_percent) << "}";
  }
  out << "],\"per_minute\":[";
  for (size_t i = 0; i < t.minutes.size(); ++i) {
    const MinuteStats& m = t.minutes[i];
    std::snprintf(buf, sizeof buf,
                  "%s{\"minute\":%zu,\"deltas\":%zu,\"p50_ms\":%.3f,\"p99_ms\":%.3f,"
                  "\"p999_ms\":%.3f,\"max_ms\":%.3f,\"worst_second\":%zu,"
                  "\"worst_second_p99_ms\":%.3f,",
                  i ? "," : "", m.minute + 1, m.delta.count, m.delta.p50, m.delta.p99, m.delta.p999,
                  m.delta.max, m.worst_second, m.worst_second_p99);
    out << buf << "\"rss_min_mib\":" << optional_json(m.rss_min_mib)
        << ",\"rss_max_mib\":" << optional_json(m.rss_max_mib)
        << ",\"cpu_mean_percent\":" << optional_json(m.cpu_mean_percent)
        << ",\"tester_cpu_mean_percent\":" << optional_json(m.tester_cpu_mean_percent)
        << ",\"steal_mean_percent\":" << optional_json(m.steal_mean_percent) << "}";
  }
  std::snprintf(buf, sizeof buf, "],\"worst_second\":{\"t\":%zu,\"p99_ms\":%.3f}", t.worst_second,
                t.worst_second_p99);
  out << buf;
  if (t.worst_quiet_second) {
    std::snprintf(buf, sizeof buf,
                  ",\"worst_quiet_second\":{\"t\":%zu,\"p99_ms\":%.3f,\"steal_below_percent\":%.0f,"
                  "\"stolen_seconds\":%zu}",
                  *t.worst_quiet_second, t.worst_quiet_second_p99, kQuietStealPercent,
                  t.stolen_seconds);
    out << buf;
  } else {
    out << ",\"worst_quiet_second\":null";
  }
}

// Per minute, for runs of more than one: what a soak is judged by.
void write_minutes_table(const Timeline& t, std::ostream& out) {
  char buf[256];
  if (t.minutes.size() > 1) {
    out << "  per minute (edit -> deltas decoded, ms; voxeld RSS MiB; CPU % of a core: voxeld, "
           "this tester, stolen from the VM)\n"
           "    min  edits    p50     p99   p99.9     max  worst s p99    RSS min..max  "
           "voxeld tester steal\n";
    auto cell = [](const std::optional<double>& v, int width) {
      char text[32];
      if (v)
        std::snprintf(text, sizeof text, " %*.0f", width, *v);
      else
        std::snprintf(text, sizeof text, " %*s", width, "-");
      return std::string(text);
    };
    for (const MinuteStats& m : t.minutes) {
      std::snprintf(buf, sizeof buf, "    %3zu %6zu %6.1f %7.1f %7.1f %7.1f %5zu %7.1f ",
                    m.minute + 1, m.delta.count, m.delta.p50, m.delta.p99, m.delta.p999,
                    m.delta.max, m.worst_second, m.worst_second_p99);
      out << buf << cell(m.rss_min_mib, 6) << ".." << cell(m.rss_max_mib, 6).substr(1)
          << cell(m.cpu_mean_percent, 6) << cell(m.tester_cpu_mean_percent, 6)
          << cell(m.steal_mean_percent, 5) << "\n";
    }
  }
  if (!t.any_deltas) {
    out << "  worst second: none (no edit was answered with its delta)\n";
    return;
  }
  std::snprintf(buf, sizeof buf, "  worst second: %zu s into the run, edit->delta p99 %.1f ms\n",
                t.worst_second, t.worst_second_p99);
  out << buf;
  if (t.worst_quiet_second) {
    std::snprintf(buf, sizeof buf,
                  "  worst second with under %.0f %% of a core stolen by the host: %zu s, p99 "
                  "%.1f ms (%zu seconds had more stolen)\n",
                  kQuietStealPercent, *t.worst_quiet_second, t.worst_quiet_second_p99,
                  t.stolen_seconds);
    out << buf;
  }
}

}  // namespace

uint64_t LoadStats::error_count() const { return total(errors); }
uint64_t LoadStats::disconnect_count() const { return total(disconnects); }

void write_table(const LoadStats& s, std::ostream& out) {
  const auto result = percentiles(values(s.edit_to_result)),
             delta = percentiles(values(s.edit_to_delta));
  const auto view = percentiles(s.first_view_ms);
  const double per_player_s = std::max(1e-9, s.duration_s * std::max(1, s.players));
  char buf[512];
  out << (s.attack.mix.empty() ? "voxel-loadtest results\n"
                               : "voxel-loadtest results (honest players; attackers below)\n");
  std::snprintf(buf, sizeof buf,
                "  players %d (%d connected), %.1f s, %llu edits sent (%llu refused)\n", s.players,
                s.players_connected, s.duration_s, static_cast<unsigned long long>(s.edits_sent),
                static_cast<unsigned long long>(s.refused));
  out << buf;
  out << "  latency (ms)               p50      p95      p99    p99.9      max    count\n";
  std::vector<std::pair<const char*, Percentiles>> rows = {{"edit -> EditResult   ", result},
                                                           {"edit -> deltas decoded", delta},
                                                           {"first full view      ", view}};
  if (!s.reconnect_ms.empty()) {
    rows.emplace_back("reconnected          ", percentiles(s.reconnect_ms));
    rows.emplace_back("view after reconnect ", percentiles(s.reconnect_view_ms));
  }
  for (const auto& [name, p] : rows) {
    std::snprintf(buf, sizeof buf, "  %s %8.2f %8.2f %8.2f %8.2f %8.2f %8zu\n", name, p.p50, p.p95,
                  p.p99, p.p999, p.max, p.count);
    out << buf;
  }
  std::snprintf(
      buf, sizeof buf,
      "  received per player: %.0f bytes/s, %.1f messages/s; %llu chunk meshes streamed\n",
      static_cast<double>(s.bytes_received) / per_player_s,
      static_cast<double>(s.messages_received) / per_player_s,
      static_cast<unsigned long long>(s.chunks_streamed));
  out << buf;
  out << "  errors: " << s.error_count() << ", disconnects: " << s.disconnect_count()
      << ", decode failures: " << s.decode_failures;
  if (s.verified) out << ", verify mismatches: " << s.verify_mismatches;
  out << "\n";
  for (const auto& [k, v] : s.errors) out << "    error " << k << ": " << v << "\n";
  for (const auto& [k, v] : s.disconnects) out << "    disconnect " << k << ": " << v << "\n";
  if (s.edits_resent > 0)
    out << "  edits resent after a reconnect: " << s.edits_resent << " ("
        << s.resent_already_applied << " answered already_applied)\n";
  for (const auto& [k, v] : s.refused_by_status) out << "    refused " << k << ": " << v << "\n";
  if (!s.server_rss_kib.empty()) {
    std::snprintf(buf, sizeof buf,
                  "voxeld RSS (pid %d): start %.1f MiB, max %.1f MiB, final %.1f MiB\n",
                  s.server_pid, s.server_rss_kib.front() / 1024,
                  *std::max_element(s.server_rss_kib.begin(), s.server_rss_kib.end()) / 1024,
                  s.server_rss_kib.back() / 1024);
    out << buf;
  }
  write_minutes_table(timeline(s), out);
  write_attack_table(s.attack, out);
}

void write_json(const LoadStats& s, std::ostream& out) {
  const double per_player_s = std::max(1e-9, s.duration_s * std::max(1, s.players));
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "{\"players\":%d,\"players_connected\":%d,\"duration_s\":%.3f,\"edits_sent\":%llu,"
                "\"refused\":%llu,",
                s.players, s.players_connected, s.duration_s,
                static_cast<unsigned long long>(s.edits_sent),
                static_cast<unsigned long long>(s.refused));
  out << buf;
  json_percentiles(out, "edit_to_result_ms", percentiles(values(s.edit_to_result)));
  out << ",";
  json_percentiles(out, "edit_to_delta_ms", percentiles(values(s.edit_to_delta)));
  out << ",";
  json_percentiles(out, "first_view_ms", percentiles(s.first_view_ms));
  if (!s.reconnect_ms.empty()) {
    out << ",";
    json_percentiles(out, "reconnect_ms", percentiles(s.reconnect_ms));
    out << ",";
    json_percentiles(out, "reconnect_view_ms", percentiles(s.reconnect_view_ms));
    out << ",\"edits_resent\":" << s.edits_resent
        << ",\"resent_already_applied\":" << s.resent_already_applied;
  }
  std::snprintf(buf, sizeof buf,
                ",\"bytes_per_player_per_s\":%.1f,\"messages_per_player_per_s\":%.2f,\"chunks_"
                "streamed\":%llu,"
                "\"decode_failures\":%llu,\"errors\":%llu,\"disconnects\":%llu,",
                static_cast<double>(s.bytes_received) / per_player_s,
                static_cast<double>(s.messages_received) / per_player_s,
                static_cast<unsigned long long>(s.chunks_streamed),
                static_cast<unsigned long long>(s.decode_failures),
                static_cast<unsigned long long>(s.error_count()),
                static_cast<unsigned long long>(s.disconnect_count()));
  out << buf;
  json_map(out, "errors_by_cause", s.errors);
  out << ",";
  json_map(out, "disconnects_by_cause", s.disconnects);
  out << ",";
  json_map(out, "refused_by_status", s.refused_by_status);
  out << ",\"verified\":" << (s.verified ? "true" : "false")
      << ",\"verify_mismatches\":" << s.verify_mismatches;
  write_rss_json(s, out);
  if (!s.attack.mix.empty()) {
    out << ",";
    write_attack_json(s.attack, out);
  }
  write_timeline_json(timeline(s), out);
  out << "}\n";
}

}  // namespace vox::loadtest
