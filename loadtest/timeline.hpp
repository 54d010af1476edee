// A load test over time: per second and per minute of the run, the edit -> delta
// percentiles, the bytes received and voxeld's RSS and CPU, the worst second, and the
// limits an operator set (--max-p99-ms, --max-rss) checked minute by minute. Pure
// functions of LoadStats, for the reports (table, JSON, SVG) and the exit code.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "loadtest/load_stats.hpp"

namespace vox::loadtest {

struct SecondStats {
  Percentiles delta;                  // edit -> decoded delta of the edits answered this second
  double bytes = 0;                   // received by all players
  std::optional<double> rss_mib;      // voxeld's, sampled at the start of the second
  std::optional<double> cpu_percent;  // voxeld's over the second, % of one core
  std::optional<double> tester_cpu_percent, steal_percent;  // the load tester's; stolen
};

struct MinuteStats {
  size_t minute = 0;        // 0 = the first minute of the run (the ramp included)
  Percentiles delta;        // over every edit answered in the minute
  size_t worst_second = 0;  // of the run, the second of the minute with the highest p99
  double worst_second_p99 = 0;
  std::optional<double> rss_min_mib, rss_max_mib, cpu_mean_percent;
  std::optional<double> tester_cpu_mean_percent, steal_mean_percent;
};

struct Timeline {
  std::vector<SecondStats> seconds;
  std::vector<MinuteStats> minutes;
  size_t worst_second = 0;  // the second of the run with the highest p99 (0 when no edits)
  double worst_second_p99 = 0;
  // The same among the seconds in which the VM lost less than kQuietStealPercent of a core
  // to its host (steal time): what the server did when it had its CPU. Unset when steal
  // was not sampled or no such second had an answer.
  std::optional<size_t> worst_quiet_second;
  double worst_quiet_second_p99 = 0;
  size_t stolen_seconds = 0;  // seconds with answers and at least that much stolen
  bool any_deltas = false;    // some edit was answered with its delta
  double editing_s = 0;       // when the players stopped editing (LoadStats::duration_s)
};

inline constexpr double kQuietStealPercent = 5.0;

Timeline timeline(const LoadStats& s);

struct Limits {
  std::optional<double> max_p99_ms;   // edit -> delta p99 of any minute
  std::optional<double> max_rss_mib;  // voxeld's RSS at any sample
};
// One line per minute that broke a limit ("minute 3: edit->delta p99 182.0 ms >
// --max-p99-ms 150.0"); with --max-p99-ms a minute of editing in which no edit was answered
// at all breaks it too (a server that hangs). Empty when every minute kept them.
std::vector<std::string> limit_breaches(const Timeline& t, const Limits& limits);

}  // namespace vox::loadtest
