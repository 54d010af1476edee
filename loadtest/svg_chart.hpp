// Line charts in SVG as an operator reads them: each panel has a title, labelled axes
// with ticks at round numbers and their units, a legend, an optional dashed goal line and
// shaded bands (the minutes of a long run). No dependency: the load tester's reports.
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace vox::loadtest {

struct ChartSeries {
  std::string name;  // in the legend
  std::string colour;
  std::vector<std::pair<double, double>> points;  // (x, y), x ascending
  bool step = false;     // drawn as steps (a value held until the next point)
  bool markers = false;  // a dot at each point, labelled with its y
  double width = 1.5;
};

struct ChartPanel {
  std::string title;
  std::string x_label, y_label;  // with units: "time (minutes)", "latency (ms)"
  double x_min = 0, x_max = 1;
  double x_scale = 1;  // tick labels show x / x_scale (seconds drawn as minutes: 60)
  bool log_y = false;  // powers of ten; values below y_floor are drawn at it
  double y_floor = 1;
  std::optional<double> y_max;  // default: the largest value (and the goal) with headroom
  std::vector<ChartSeries> series;
  std::optional<std::pair<double, std::string>> goal;  // y, legend text
  std::vector<std::pair<double, double>> bands;        // x ranges shaded light grey
};

// Round tick values covering [lo, hi]: about `target` of them, steps of 1, 2, 2.5 or 5
// times a power of ten.
std::vector<double> nice_ticks(double lo, double hi, int target = 5);
// A number as people write it: 0.25, 12.5, 950, 1,200, 35,000, 1.2 M.
std::string human_number(double v);

void write_chart(const std::string& heading, const std::vector<ChartPanel>& panels,
                 std::ostream& out);

}  // namespace vox::loadtest
