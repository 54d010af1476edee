#include "loadtest/timeline.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vox::loadtest {

namespace {

constexpr size_t kSecondsPerMinute = 60;

// The samples that fall in each second of the run, clamped into [0, seconds).
std::vector<std::vector<double>> by_second(const std::vector<LatencySample>& samples,
                                           size_t seconds) {
  std::vector<std::vector<double>> buckets(seconds);
  for (const auto& x : samples) {
    const auto i = static_cast<size_t>(std::max(0.0, x.at_s));
    buckets[std::min(seconds - 1, i)].push_back(x.ms);
  }
  return buckets;
}

MinuteStats minute_of(const Timeline& t, const std::vector<std::vector<double>>& buckets,
                      size_t minute) {
  MinuteStats m;
  m.minute = minute;
  const size_t first = minute * kSecondsPerMinute,
               end = std::min(t.seconds.size(), first + kSecondsPerMinute);
  std::vector<double> all;
  struct Mean {
    double sum = 0;
    size_t n = 0;
    void add(const std::optional<double>& v) {
      if (v) sum += *v, ++n;
    }
    std::optional<double> value() const {
      return n ? std::optional(sum / static_cast<double>(n)) : std::nullopt;
    }
  } cpu, tester, steal;
  bool any_edits = false;
  for (size_t i = first; i < end; ++i) {
    all.insert(all.end(), buckets[i].begin(), buckets[i].end());
    const SecondStats& s = t.seconds[i];
    if (s.delta.count > 0 && (!any_edits || s.delta.p99 > m.worst_second_p99)) {
      m.worst_second = i;
      m.worst_second_p99 = s.delta.p99;
      any_edits = true;
    }
    if (s.rss_mib) {
      m.rss_min_mib = std::min(m.rss_min_mib.value_or(*s.rss_mib), *s.rss_mib);
      m.rss_max_mib = std::max(m.rss_max_mib.value_or(*s.rss_mib), *s.rss_mib);
    }
    cpu.add(s.cpu_percent);
    tester.add(s.tester_cpu_percent);
    steal.add(s.steal_percent);
  }
  m.delta = percentiles(std::move(all));
  m.cpu_mean_percent = cpu.value();
  m.tester_cpu_mean_percent = tester.value();
  m.steal_mean_percent = steal.value();
  return m;
}

// Sample i of a once-a-second series; nullopt past its end or where it is NaN (a sample
// the sampler could not take: it keeps the others in their seconds).
std::optional<double> sampled(const std::vector<double>& series, size_t i, double scale = 1) {
  if (i >= series.size() || std::isnan(series[i])) return std::nullopt;
  return series[i] * scale;
}

std::string format(const char* pattern, size_t minute, double value, double limit) {
  char line[160];
  std::snprintf(line, sizeof line, pattern, minute, value, limit);
  return line;
}

}  // namespace

Timeline timeline(const LoadStats& s) {
  Timeline t;
  t.any_deltas = !s.edit_to_delta.empty();
  t.editing_s = s.duration_s;
  const size_t seconds = std::max<size_t>(
      {1, s.bytes_per_second.size(), s.server_rss_kib.size(), s.server_cpu_percent.size()});
  auto buckets = by_second(s.edit_to_delta, seconds);
  t.seconds.resize(seconds);
  for (size_t i = 0; i < seconds; ++i) {
    SecondStats& second = t.seconds[i];
    second.delta = percentiles(buckets[i]);
    if (i < s.bytes_per_second.size()) second.bytes = s.bytes_per_second[i];
    second.rss_mib = sampled(s.server_rss_kib, i, 1.0 / 1024);
    second.cpu_percent = sampled(s.server_cpu_percent, i);
    second.tester_cpu_percent = sampled(s.tester_cpu_percent, i);
    second.steal_percent = sampled(s.host_steal_percent, i);
    if (second.delta.count > 0 && second.delta.p99 > t.worst_second_p99) {
      t.worst_second = i;
      t.worst_second_p99 = second.delta.p99;
    }
    if (second.delta.count > 0 && second.steal_percent) {
      if (*second.steal_percent >= kQuietStealPercent) {
        ++t.stolen_seconds;
      } else if (!t.worst_quiet_second || second.delta.p99 > t.worst_quiet_second_p99) {
        t.worst_quiet_second = i;
        t.worst_quiet_second_p99 = second.delta.p99;
      }
    }
  }
  for (size_t m = 0; m * kSecondsPerMinute < seconds; ++m)
    t.minutes.push_back(minute_of(t, buckets, m));
  return t;
}

std::vector<std::string> limit_breaches(const Timeline& t, const Limits& limits) {
  std::vector<std::string> lines;
  for (const MinuteStats& m : t.minutes) {
    if (limits.max_p99_ms && m.delta.count > 0 && m.delta.p99 > *limits.max_p99_ms) {
      lines.push_back(format("minute %zu: edit->delta p99 %.1f ms > --max-p99-ms %.1f",
                             m.minute + 1, m.delta.p99, *limits.max_p99_ms));
    }
    // A minute that began at least 10 s before the editing stopped, without one answer.
    const double begins_s = static_cast<double>(m.minute * kSecondsPerMinute);
    if (limits.max_p99_ms && m.delta.count == 0 && begins_s + 10 < t.editing_s) {
      lines.push_back("minute " + std::to_string(m.minute + 1) +
                      ": no edit was answered with its delta (--max-p99-ms)");
    }
    if (limits.max_rss_mib && m.rss_max_mib && *m.rss_max_mib > *limits.max_rss_mib) {
      lines.push_back(format("minute %zu: voxeld RSS %.1f MiB > --max-rss %.1f MiB", m.minute + 1,
                             *m.rss_max_mib, *limits.max_rss_mib));
    }
  }
  return lines;
}

}  // namespace vox::loadtest
