#include "loadtest/load_stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>

namespace vox::loadtest {

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.count = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  // Nearest rank: the smallest sample that at least q of them do not exceed, rank
  // ceil(q * n), in integers (q * n in floating point can land just above a whole number).
  auto at = [&v](size_t per_mille) { return v[(per_mille * v.size() + 999) / 1000 - 1]; };
  p.p50 = at(500);
  p.p95 = at(950);
  p.p99 = at(990);
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
                "\"%s\":{\"p50\":%.3f,\"p95\":%.3f,\"p99\":%.3f,\"max\":%.3f,\"count\":%zu}", name,
                p.p50, p.p95, p.p99, p.max, p.count);
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

// Percentiles of the samples that fall in each second of the test.
std::vector<Percentiles> per_second(const std::vector<LatencySample>& samples, size_t seconds) {
  std::vector<std::vector<double>> buckets(std::max<size_t>(1, seconds));
  for (const auto& x : samples) {
    buckets[std::min(buckets.size() - 1, static_cast<size_t>(std::max(0.0, x.at_s)))].push_back(
        x.ms);
  }
  std::vector<Percentiles> out;
  out.reserve(buckets.size());
  for (auto& b : buckets) out.push_back(percentiles(std::move(b)));
  return out;
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
  out << "  latency (ms)               p50      p95      p99      max    count\n";
  for (const auto& [name, p] : {std::pair{"edit -> EditResult   ", result},
                                {"edit -> deltas decoded", delta},
                                {"first full view      ", view}}) {
    std::snprintf(buf, sizeof buf, "  %s %8.2f %8.2f %8.2f %8.2f %8zu\n", name, p.p50, p.p95, p.p99,
                  p.max, p.count);
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
  for (const auto& [k, v] : s.refused_by_status) out << "    refused " << k << ": " << v << "\n";
  if (!s.server_rss_kib.empty()) {
    std::snprintf(buf, sizeof buf,
                  "voxeld RSS (pid %d): start %.1f MiB, max %.1f MiB, final %.1f MiB\n",
                  s.server_pid, s.server_rss_kib.front() / 1024,
                  *std::max_element(s.server_rss_kib.begin(), s.server_rss_kib.end()) / 1024,
                  s.server_rss_kib.back() / 1024);
    out << buf;
  }
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
  // Over time: per second of the test, edit -> delta percentiles and bytes received.
  const auto seconds = per_second(s.edit_to_delta, s.bytes_per_second.size());
  out << ",\"per_second\":[";
  for (size_t i = 0; i < seconds.size(); ++i) {
    std::snprintf(buf, sizeof buf,
                  "%s{\"t\":%zu,\"deltas\":%zu,\"p50_ms\":%.3f,\"p99_ms\":%.3f,\"bytes\":%.0f}",
                  i ? "," : "", i, seconds[i].count, seconds[i].p50, seconds[i].p99,
                  i < s.bytes_per_second.size() ? s.bytes_per_second[i] : 0.0);
    out << buf;
  }
  out << "]}\n";
}

// Panels over time: edit -> delta latency (p50, p99 per second), bytes received per second
// and, when it was sampled, voxeld's RSS.
void write_svg(const LoadStats& s, std::ostream& out) {
  const auto buckets = per_second(s.edit_to_delta, s.bytes_per_second.size());
  std::vector<double> p50, p99, rss_mib;
  double max_ms = 1, max_bytes = 1, max_mib = 1;
  for (const auto& p : buckets) {
    p50.push_back(p.p50);
    p99.push_back(p.p99);
    max_ms = std::max(max_ms, p.p99);
  }
  for (double b : s.bytes_per_second) max_bytes = std::max(max_bytes, b);
  for (double kib : s.server_rss_kib) rss_mib.push_back(kib / 1024);
  for (double mib : rss_mib) max_mib = std::max(max_mib, mib);
  const int panels = rss_mib.empty() ? 2 : 3;
  const double w = 800, h = 220, left = 60, gap = 60;
  // Each series spreads over the full width: one point a second, from the start.
  auto polyline = [&](const std::vector<double>& v, double top, double scale, const char* colour) {
    out << "<polyline fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"1.5\" points=\"";
    const double n = static_cast<double>(v.size());
    for (size_t i = 0; i < v.size(); ++i)
      out << left + (w - left - 20) * (n > 1 ? static_cast<double>(i) / (n - 1) : 0.0) << ","
          << top + h - v[i] / scale * h << " ";
    out << "\"/>\n";
  };
  auto number = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return std::string(buf);
  };
  auto title = [&](int panel, const std::string& text) {
    out << "<text x=\"" << left << "\" y=\"" << panel * (h + gap) + 40
        << "\" font-family=\"sans-serif\" font-size=\"14\">" << text << "</text>\n";
  };
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\""
      << panels * (h + gap) + gap << "\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  title(0, "voxel-loadtest: " + std::to_string(s.players) +
               (s.attack.mix.empty() ? "" : " honest") +
               " players, edit to decoded delta (ms): p50 blue, p99 red; max " + number(max_ms) +
               " ms");
  title(1, "bytes received per second, all players; max " + number(max_bytes));
  if (panels == 3) title(2, "voxeld RSS (MiB); max " + number(max_mib));
  for (int panel = 0; panel < panels; ++panel) {
    const double top = gap + panel * (h + gap);
    out << "<line x1=\"" << left << "\" y1=\"" << top + h << "\" x2=\"" << w - 20 << "\" y2=\""
        << top + h << "\" stroke=\"black\"/><line x1=\"" << left << "\" y1=\"" << top << "\" x2=\""
        << left << "\" y2=\"" << top + h << "\" stroke=\"black\"/>\n";
  }
  polyline(p50, gap, max_ms, "#2060c0");
  polyline(p99, gap, max_ms, "#c02020");
  polyline(s.bytes_per_second, h + 2 * gap, max_bytes, "#208040");
  if (panels == 3) polyline(rss_mib, 2 * h + 3 * gap, max_mib, "#8040a0");
  out << "</svg>\n";
}

void write_sweep_svg(const std::vector<SweepPoint>& points, double limit_ms, std::ostream& out) {
  const double w = 800, h = 400, left = 70, bottom = 50, top = 40;
  double max_players = 1, max_ms = limit_ms * 1.2;
  for (const auto& p : points) {
    max_players = std::max(max_players, static_cast<double>(p.players));
    max_ms = std::max(max_ms, p.p99_ms * 1.1);
  }
  auto x_of = [&](double players) { return left + (w - left - 30) * players / max_players; };
  auto y_of = [&](double ms) { return h - bottom - (h - bottom - top) * ms / max_ms; };
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h << "\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<text x=\"" << left
      << "\" y=\"24\" font-family=\"sans-serif\" font-size=\"14\">voxel-loadtest sweep: "
      << "edit to decoded delta p99 (ms) against players; dashed: " << limit_ms << " ms</text>\n"
      << "<line x1=\"" << left << "\" y1=\"" << h - bottom << "\" x2=\"" << w - 30 << "\" y2=\""
      << h - bottom << "\" stroke=\"black\"/><line x1=\"" << left << "\" y1=\"" << top << "\" x2=\""
      << left << "\" y2=\"" << h - bottom << "\" stroke=\"black\"/>\n"
      << "<line x1=\"" << left << "\" y1=\"" << y_of(limit_ms) << "\" x2=\"" << w - 30 << "\" y2=\""
      << y_of(limit_ms)
      << "\" stroke=\"#c02020\" stroke-dasharray=\"6 4\"/>\n<polyline fill=\"none\" "
         "stroke=\"#2060c0\" stroke-width=\"2\" points=\"";
  for (const auto& p : points) out << x_of(p.players) << "," << y_of(p.p99_ms) << " ";
  out << "\"/>\n";
  for (const auto& p : points) {
    out << "<circle cx=\"" << x_of(p.players) << "\" cy=\"" << y_of(p.p99_ms)
        << "\" r=\"4\" fill=\"" << (p.errors == 0 ? "#2060c0" : "#c02020") << "\"/><text x=\""
        << x_of(p.players) - 10 << "\" y=\"" << h - bottom + 18
        << "\" font-family=\"sans-serif\" font-size=\"11\">" << p.players << "</text><text x=\""
        << x_of(p.players) + 6 << "\" y=\"" << y_of(p.p99_ms) - 6
        << "\" font-family=\"sans-serif\" font-size=\"11\">" << static_cast<int>(p.p99_ms)
        << "</text>\n";
  }
  out << "</svg>\n";
}

}  // namespace vox::loadtest
