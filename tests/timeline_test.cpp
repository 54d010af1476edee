// The load test over time (loadtest/timeline.hpp) and its charts (svg_chart, report_svg):
// per-second and per-minute figures, the worst second, the soak limits, and charts an
// operator can read (axes with round ticks and units, a legend, a goal line).
#include "loadtest/timeline.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <limits>
#include <regex>
#include <sstream>

#include "loadtest/host_sampler.hpp"
#include "loadtest/report_svg.hpp"
#include "loadtest/svg_chart.hpp"

namespace {

using vox::loadtest::LoadStats;

// A run of `seconds`, one edit answered in `ms` every 10 ms of it, but the stalls.
LoadStats steady_run(size_t seconds, double ms) {
  LoadStats s;
  s.players = 300;
  s.duration_s = static_cast<double>(seconds);
  s.bytes_per_second.assign(seconds, 2.5e6);
  for (size_t i = 0; i < seconds * 100; ++i) s.edit_to_delta.push_back({i * 0.01, ms});
  for (size_t i = 0; i < seconds; ++i) {
    s.server_rss_kib.push_back(400.0 * 1024 + static_cast<double>(i));
    s.server_cpu_percent.push_back(120);
    s.tester_cpu_percent.push_back(60);
    s.host_steal_percent.push_back(i % 2 ? 10 : std::numeric_limits<double>::quiet_NaN());
  }
  return s;
}

TEST(Timeline, GivesEachSecondAndMinuteItsOwnPercentilesAndFindsTheWorstSecond) {
  LoadStats s = steady_run(150, 20);
  for (int i = 0; i < 10; ++i) s.edit_to_delta.push_back({95.5, 3000});  // a stall in second 95
  const auto t = vox::loadtest::timeline(s);
  ASSERT_EQ(t.seconds.size(), 150u);
  ASSERT_EQ(t.minutes.size(), 3u);  // the last minute is the 30 s left
  EXPECT_EQ(t.seconds[10].delta.count, 100u);
  EXPECT_EQ(t.seconds[95].delta.count, 110u);
  EXPECT_EQ(t.seconds[95].delta.p99, 3000);
  EXPECT_EQ(t.worst_second, 95u);
  EXPECT_EQ(t.worst_second_p99, 3000);
  EXPECT_EQ(t.minutes[0].delta.p99, 20);
  EXPECT_EQ(t.minutes[1].delta.count, 6010u);
  EXPECT_EQ(t.minutes[1].delta.max, 3000);
  EXPECT_EQ(t.minutes[1].delta.p999, 3000);  // 10 in 6,010 is more than 0.1 %
  EXPECT_EQ(t.minutes[1].delta.p99, 20);
  EXPECT_EQ(t.minutes[1].worst_second, 95u);
  EXPECT_EQ(t.minutes[2].delta.count, 3000u);
  EXPECT_DOUBLE_EQ(*t.minutes[0].rss_min_mib, 400.0);
  EXPECT_DOUBLE_EQ(*t.minutes[0].rss_max_mib, 400.0 + 59.0 / 1024);
  EXPECT_DOUBLE_EQ(*t.minutes[2].cpu_mean_percent, 120);
  EXPECT_DOUBLE_EQ(*t.minutes[2].tester_cpu_mean_percent, 60);
  EXPECT_DOUBLE_EQ(*t.minutes[2].steal_mean_percent, 10);  // the seconds it could be read
  EXPECT_FALSE(t.seconds[0].steal_percent);
}

TEST(Timeline, TheWorstQuietSecondLeavesOutSecondsTheHostStoleTheCpuIn) {
  LoadStats s = steady_run(120, 20);
  for (size_t i = 0; i < 120; ++i) s.host_steal_percent[i] = 1.0;
  s.host_steal_percent[40] = 70.0;  // the host took most of a core: a slow second
  s.host_steal_percent[41] = 4.0;
  for (int i = 0; i < 10; ++i) s.edit_to_delta.push_back({40.5, 900});
  for (int i = 0; i < 10; ++i) s.edit_to_delta.push_back({41.5, 60});
  const auto t = vox::loadtest::timeline(s);
  EXPECT_EQ(t.worst_second, 40u);
  ASSERT_TRUE(t.worst_quiet_second);
  EXPECT_EQ(*t.worst_quiet_second, 41u);
  EXPECT_EQ(t.worst_quiet_second_p99, 60);
  EXPECT_EQ(t.stolen_seconds, 1u);
  std::ostringstream table;
  vox::loadtest::write_table(s, table);
  EXPECT_NE(table.str().find("stolen by the host: 41 s, p99 60.0 ms (1 seconds had more stolen)"),
            std::string::npos)
      << table.str();
  s.host_steal_percent.clear();  // not sampled: no such figure
  EXPECT_FALSE(vox::loadtest::timeline(s).worst_quiet_second);
}

TEST(Timeline, ARunWithoutServerSamplesHasNoRssOrCpuFigures) {
  LoadStats s = steady_run(5, 10);
  s.server_rss_kib.clear();
  s.server_cpu_percent.clear();
  s.tester_cpu_percent.clear();
  s.host_steal_percent.clear();
  const auto t = vox::loadtest::timeline(s);
  EXPECT_FALSE(t.seconds[0].rss_mib);
  EXPECT_FALSE(t.minutes[0].rss_max_mib);
  EXPECT_FALSE(t.minutes[0].cpu_mean_percent);
  EXPECT_TRUE(vox::loadtest::limit_breaches(t, {.max_p99_ms = 50, .max_rss_mib = 1}).empty());
}

TEST(Timeline, LimitsAreCheckedMinuteByMinuteAndNameTheMinute) {
  LoadStats s = steady_run(180, 20);
  for (int i = 0; i < 100; ++i) s.edit_to_delta.push_back({130.0, 400});  // 1.7 % of minute 3
  const auto t = vox::loadtest::timeline(s);
  EXPECT_TRUE(vox::loadtest::limit_breaches(t, {}).empty());
  EXPECT_TRUE(vox::loadtest::limit_breaches(t, {.max_p99_ms = 400, .max_rss_mib = 401}).empty());
  const auto p99 = vox::loadtest::limit_breaches(t, {.max_p99_ms = 150});
  ASSERT_EQ(p99.size(), 1u);
  EXPECT_NE(p99[0].find("minute 3: edit->delta p99 400.0 ms > --max-p99-ms 150.0"),
            std::string::npos)
      << p99[0];
  const auto rss = vox::loadtest::limit_breaches(t, {.max_rss_mib = 400.1});
  ASSERT_EQ(rss.size(), 2u);  // minutes 2 and 3 grew past 400.1 MiB
  EXPECT_NE(rss[0].find("minute 2: voxeld RSS"), std::string::npos) << rss[0];
}

// Found in review: a server that hung gave minutes without a single answer, and a minute
// without answers had no p99 to break the limit with.
TEST(Timeline, AMinuteOfEditingWithoutOneAnswerBreaksTheLatencyLimit) {
  LoadStats s = steady_run(150, 20);
  s.edit_to_delta.resize(5000);  // answers stop 50 s into the run; editing went on to 150 s
  const auto t = vox::loadtest::timeline(s);
  EXPECT_TRUE(vox::loadtest::limit_breaches(t, {.max_rss_mib = 1000}).empty());
  const auto lines = vox::loadtest::limit_breaches(t, {.max_p99_ms = 150});
  ASSERT_EQ(lines.size(), 2u);  // minutes 2 and 3 (3 begins 120 s in, editing stopped at 150)
  EXPECT_EQ(lines[0], "minute 2: no edit was answered with its delta (--max-p99-ms)");
  s.duration_s = 125;  // the third minute began just before the end: not judged
  EXPECT_EQ(vox::loadtest::limit_breaches(vox::loadtest::timeline(s), {.max_p99_ms = 150}).size(),
            1u);
}

TEST(HostSampler, ReadsStealFromTheAggregateCpuLineOnly) {
  EXPECT_EQ(
      vox::loadtest::parse_steal_ticks("cpu  10 2 30 4000 5 0 6 77 0 0\ncpu0 1 1 1 1 1 1 1 9\n"),
      77u);
  EXPECT_FALSE(vox::loadtest::parse_steal_ticks("cpu0 1 1 1 1 1 1 1 9\n"));
  EXPECT_FALSE(vox::loadtest::parse_steal_ticks("cpu  10 2 30 4000\ncpu0 1 1 1 1 1 1 1 9\n"));
  EXPECT_FALSE(vox::loadtest::parse_steal_ticks(""));
}

TEST(HostSampler, GivesOneFigurePerSecondAfterTheFirstSample) {
  vox::loadtest::HostSampler sampler;
  sampler.sample();
  EXPECT_TRUE(sampler.tester_cpu_percent().empty());
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  volatile double x = 0;
  while (std::chrono::steady_clock::now() < until) x = x + 1e-9;
  sampler.sample();
  ASSERT_EQ(sampler.tester_cpu_percent().size(), 1u);
  ASSERT_EQ(sampler.steal_percent().size(), 1u);
  EXPECT_GT(sampler.tester_cpu_percent()[0], 0.0);
  EXPECT_GE(sampler.steal_percent()[0], 0.0);
}

TEST(SvgChart, TicksAreRoundNumbersCoveringTheRange) {
  EXPECT_EQ(vox::loadtest::nice_ticks(0, 100), (std::vector<double>{0, 20, 40, 60, 80, 100}));
  EXPECT_EQ(vox::loadtest::nice_ticks(0, 30, 6), (std::vector<double>{0, 5, 10, 15, 20, 25, 30}));
  EXPECT_EQ(vox::loadtest::nice_ticks(0, 1), (std::vector<double>{0, 0.2, 0.4, 0.6, 0.8, 1}));
  EXPECT_EQ(vox::loadtest::nice_ticks(0, 12.5, 5), (std::vector<double>{0, 2.5, 5, 7.5, 10, 12.5}));
  EXPECT_EQ(vox::loadtest::nice_ticks(3, 3), (std::vector<double>{3}));
}

TEST(SvgChart, NumbersAreWrittenAsPeopleWriteThem) {
  EXPECT_EQ(vox::loadtest::human_number(0), "0");
  EXPECT_EQ(vox::loadtest::human_number(0.25), "0.25");
  EXPECT_EQ(vox::loadtest::human_number(0.125), "0.125");
  EXPECT_EQ(vox::loadtest::human_number(0.0002), "0.0002");
  EXPECT_EQ(vox::loadtest::human_number(12.5), "12.5");
  EXPECT_EQ(vox::loadtest::human_number(950), "950");
  EXPECT_EQ(vox::loadtest::human_number(1200), "1,200");
  EXPECT_EQ(vox::loadtest::human_number(35'360'600), "35.4 M");
  EXPECT_EQ(vox::loadtest::human_number(-4500), "-4,500");
}

// What the issue found in the old charts: no axes' numbers, "max 3.53606e+07", no units.
TEST(SvgChart, ARunsChartHasAxesWithUnitsALegendAGoalAndNoScientificNumbers) {
  LoadStats s = steady_run(240, 30);
  s.bytes_per_second.assign(240, 3.53606e7);
  std::ostringstream out;
  vox::loadtest::write_svg(s, 150.0, out);
  const std::string svg = out.str();
  for (const char* text :
       {"latency (ms)", "throughput (MB/s)", "RSS (MiB)", "CPU (% of one core)", "load tester",
        "stolen (steal)", "time since the start (minutes)", "p99 per second", "p99 per minute",
        "p99.9 per minute", "goal: p99 150 ms", "stroke-dasharray", ">40<", ">4<", "#f2f2f2"}) {
    EXPECT_NE(svg.find(text), std::string::npos) << text;
  }
  EXPECT_FALSE(std::regex_search(svg, std::regex(">[^<]*[0-9]e[+-][0-9]")));
}

TEST(SvgChart, AShortRunIsInSecondsAndStallsSwitchTheLatencyAxisToLog) {
  LoadStats s = steady_run(20, 15);
  for (int i = 0; i < 5; ++i) s.edit_to_delta.push_back({7.5, 4000});
  std::ostringstream out;
  vox::loadtest::write_svg(s, std::nullopt, out);
  const std::string svg = out.str();
  EXPECT_NE(svg.find("time since the start (s)"), std::string::npos);
  EXPECT_NE(svg.find("latency (ms, log scale)"), std::string::npos);
  EXPECT_NE(svg.find(">1,000<"), std::string::npos);  // a decade tick
  EXPECT_EQ(svg.find("goal"), std::string::npos);
  EXPECT_EQ(svg.find("per minute"), std::string::npos);
}

// Found in review: a panel whose values are all 0 (an idle server's CPU) had ticks 0,
// 2e-10, ... all labelled "0".
TEST(SvgChart, AnAllZeroPanelStillHasDistinctTicks) {
  LoadStats s = steady_run(10, 5);
  s.server_cpu_percent.assign(10, 0.0);
  s.tester_cpu_percent.assign(10, 0.0);
  s.host_steal_percent.assign(10, 0.0);
  std::ostringstream out;
  vox::loadtest::write_svg(s, std::nullopt, out);
  const std::string svg = out.str();
  const size_t cpu = svg.find("CPU: voxeld");
  ASSERT_NE(cpu, std::string::npos);
  for (const char* tick : {">0.2<", ">1<"})
    EXPECT_NE(svg.find(tick, cpu), std::string::npos) << tick;
}

// The sweep chart clipped its last label: every point and label lies inside the plot.
TEST(SvgChart, TheSweepsLastPointAndItsLabelAreInsideThePlot) {
  std::ostringstream out;
  vox::loadtest::write_sweep_svg({{100, 20, 0}, {400, 60, 0}, {800, 140, 2}}, 100, out);
  const std::string svg = out.str();
  const std::regex circle("<circle cx=\"([0-9.]+)\"");
  double rightmost = 0;
  for (std::sregex_iterator it(svg.begin(), svg.end(), circle), end; it != end; ++it)
    rightmost = std::max(rightmost, std::stod((*it)[1]));
  EXPECT_GT(rightmost, 600);
  EXPECT_LT(rightmost + 20, 920 - 190);                 // the plot's right edge, before the legend
  EXPECT_EQ(svg.find("log scale"), std::string::npos);  // 140 ms is not ten times 100
  std::ostringstream saturated;
  vox::loadtest::write_sweep_svg({{300, 19.7, 0}, {800, 1390, 0}}, 100, saturated);
  EXPECT_NE(saturated.str().find("p99 latency (ms, log scale)"), std::string::npos);
  for (const char* text :
       {"players", "p99 latency (ms)", "limit: 100 ms", "a run with errors", ">800<", ">140<"}) {
    EXPECT_NE(svg.find(text), std::string::npos) << text;
  }
}

}  // namespace
