// The load test's charts (SVG): a run over time, and a sweep over player counts.
#pragma once

#include <iosfwd>
#include <optional>
#include <vector>

#include "loadtest/load_stats.hpp"

namespace vox::loadtest {

// Panels over time: edit -> decoded delta latency (p50 and p99 per second, p99 and p99.9
// per minute in runs of a few minutes or more, the goal line when given), megabytes
// received per second and, when sampled, voxeld's RSS and CPU.
void write_svg(const LoadStats& s, std::optional<double> goal_p99_ms, std::ostream& out);

// A sweep over player counts: edit -> delta p99 for each, drawn against the count with
// the limit line.
struct SweepPoint {
  int players;
  double p99_ms;
  uint64_t errors;
};
void write_sweep_svg(const std::vector<SweepPoint>& points, double limit_ms, std::ostream& out);

}  // namespace vox::loadtest
