#include "loadtest/report_svg.hpp"

#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>

#include "loadtest/svg_chart.hpp"
#include "loadtest/timeline.hpp"

namespace vox::loadtest {

namespace {

constexpr size_t kMinutesForBands = 3;  // from this long a run is drawn minute by minute

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Time runs along x in seconds; long runs label it in minutes and shade every other one.
ChartPanel time_panel(const Timeline& t, std::string title, std::string y_label) {
  ChartPanel p;
  p.title = std::move(title);
  p.y_label = std::move(y_label);
  p.x_max = static_cast<double>(t.seconds.size());
  const bool long_run = t.minutes.size() >= kMinutesForBands;
  p.x_scale = long_run ? 60 : 1;
  p.x_label = long_run ? "time since the start (minutes)" : "time since the start (s)";
  if (long_run) {
    for (size_t m = 1; m < t.minutes.size(); m += 2)
      p.bands.push_back({m * 60.0, std::min(p.x_max, (m + 1) * 60.0)});
  }
  return p;
}

// A value per minute held over the minute (a step), from `field` of each minute with edits.
ChartSeries per_minute(const Timeline& t, std::string name, std::string colour,
                       double Percentiles::*field) {
  ChartSeries s{std::move(name), std::move(colour), {}, true, false, 2.5};
  for (const MinuteStats& m : t.minutes) {
    if (m.delta.count == 0) continue;
    const double end = std::min(static_cast<double>(t.seconds.size()), (m.minute + 1) * 60.0);
    s.points.push_back({m.minute * 60.0, m.delta.*field});
    s.points.push_back({end, m.delta.*field});
  }
  return s;
}

ChartPanel latency_panel(const Timeline& t, std::optional<double> goal_ms) {
  ChartPanel p = time_panel(t, "Edit to decoded delta at the editing player", "latency (ms)");
  ChartSeries p50{"p50 per second", "#2060c0", {}, false, false, 1};
  ChartSeries p99{"p99 per second", "#e07070", {}, false, false, 1};
  std::vector<double> p99s;
  for (size_t i = 0; i < t.seconds.size(); ++i) {
    const Percentiles& d = t.seconds[i].delta;
    if (d.count == 0) continue;
    p50.points.push_back({i + 0.5, d.p50});
    p99.points.push_back({i + 0.5, d.p99});
    p99s.push_back(d.p99);
  }
  p.series = {p50, p99};
  if (t.minutes.size() >= kMinutesForBands) {
    p.series.push_back(per_minute(t, "p99 per minute", "#b03000", &Percentiles::p99));
    p.series.push_back(per_minute(t, "p99.9 per minute", "#7030a0", &Percentiles::p999));
  }
  if (goal_ms) p.goal = {{*goal_ms, "goal: p99 " + human_number(*goal_ms) + " ms"}};
  // Stalls of seconds beside a tail of tens of ms: a log axis shows both.
  p.log_y = t.worst_second_p99 > 10 * std::max(1.0, median(p99s));
  if (p.log_y) p.y_label = "latency (ms, log scale)";
  return p;
}

ChartPanel sampled_panel(const Timeline& t, std::string title, std::string y_label,
                         std::string name, std::string colour,
                         std::optional<double> SecondStats::*field) {
  ChartPanel p = time_panel(t, std::move(title), std::move(y_label));
  ChartSeries s{std::move(name), std::move(colour), {}, false, false, 1.5};
  for (size_t i = 0; i < t.seconds.size(); ++i) {
    if (const auto& v = t.seconds[i].*field) s.points.push_back({i + 0.5, *v});
  }
  p.series = {s};
  return p;
}

// Whose CPU a slow second had: voxeld's, the load tester's (its players share the
// machine) and what the hypervisor stole.
ChartPanel cpu_panel(const Timeline& t) {
  ChartPanel p = time_panel(t, "CPU: voxeld, the load tester, stolen by the hypervisor",
                            "CPU (% of one core)");
  ChartSeries voxeld{"voxeld", "#a06000", {}, false, false, 1.5};
  ChartSeries tester{"load tester", "#2080a0", {}, false, false, 1};
  ChartSeries steal{"stolen (steal)", "#c02060", {}, false, false, 1};
  for (size_t i = 0; i < t.seconds.size(); ++i) {
    const SecondStats& s = t.seconds[i];
    if (s.cpu_percent) voxeld.points.push_back({i + 0.5, *s.cpu_percent});
    if (s.tester_cpu_percent) tester.points.push_back({i + 0.5, *s.tester_cpu_percent});
    if (s.steal_percent) steal.points.push_back({i + 0.5, *s.steal_percent});
  }
  for (auto* series : {&voxeld, &tester, &steal})
    if (!series->points.empty()) p.series.push_back(std::move(*series));
  return p;
}

}  // namespace

void write_svg(const LoadStats& s, std::optional<double> goal_p99_ms, std::ostream& out) {
  const Timeline t = timeline(s);
  std::vector<ChartPanel> panels{latency_panel(t, goal_p99_ms)};
  ChartPanel bytes = time_panel(t, "Received by all players", "throughput (MB/s)");
  ChartSeries mbps{"MB per second", "#208040", {}, false, false, 1.5};
  for (size_t i = 0; i < t.seconds.size(); ++i)
    mbps.points.push_back({i + 0.5, t.seconds[i].bytes / 1e6});
  bytes.series = {mbps};
  panels.push_back(bytes);
  if (!s.server_rss_kib.empty()) {
    panels.push_back(sampled_panel(t, "voxeld resident memory", "RSS (MiB)", "RSS", "#8040a0",
                                   &SecondStats::rss_mib));
  }
  if (!s.server_cpu_percent.empty() || !s.tester_cpu_percent.empty())
    panels.push_back(cpu_panel(t));
  std::string heading = "voxel-loadtest: " + std::to_string(s.players) +
                        (s.attack.mix.empty() ? "" : " honest") + " players, " +
                        human_number(std::round(s.duration_s)) + " s";
  if (t.worst_second_p99 > 0) {
    heading += "; worst second " + std::to_string(t.worst_second) + " s (p99 " +
               human_number(t.worst_second_p99) + " ms)";
  }
  write_chart(heading, panels, out);
}

void write_sweep_svg(const std::vector<SweepPoint>& points, double limit_ms, std::ostream& out) {
  ChartPanel p;
  p.title = "Edit to decoded delta p99 against the number of players";
  p.x_label = "players";
  p.y_label = "p99 latency (ms)";
  double most = 1;
  for (const auto& pt : points) most = std::max(most, static_cast<double>(pt.players));
  p.x_max = most * 1.08;  // room for the last point's label
  ChartSeries ok{"p99 of each run", "#2060c0", {}, false, true, 2};
  ChartSeries bad{"a run with errors", "#c02020", {}, false, true, 0};
  for (const auto& pt : points) {
    ok.points.push_back({static_cast<double>(pt.players), pt.p99_ms});
    if (pt.errors > 0) bad.points.push_back({static_cast<double>(pt.players), pt.p99_ms});
  }
  p.series = {ok};
  if (!bad.points.empty()) p.series.push_back(bad);
  p.goal = {{limit_ms, "limit: " + human_number(limit_ms) + " ms"}};
  // Saturated runs (seconds) beside the ones under the limit (tens of ms): a log axis.
  double worst = 0;
  for (const auto& pt : points) worst = std::max(worst, pt.p99_ms);
  p.log_y = worst > 10 * limit_ms;
  if (p.log_y) p.y_label = "p99 latency (ms, log scale)";
  write_chart("voxel-loadtest sweep", {p}, out);
}

}  // namespace vox::loadtest
