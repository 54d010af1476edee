// --sweep: one load test per player count, and the largest count that met the p99 limit
// without errors. The counts are parsed here, strictly (the command line is input too).
#pragma once

#include <ostream>
#include <string_view>
#include <vector>

#include "loadtest/load_test.hpp"
#include "loadtest/report_svg.hpp"
#include "proto/result.hpp"

namespace vox::loadtest {

// "N1,N2,...": each a whole number of players 1..10000; at most 64 of them.
proto::Result<std::vector<int>> parse_sweep_counts(std::string_view text);

struct SweepResult {
  std::vector<SweepPoint> points;
  int best = 0;             // largest count with p99 <= limit and no errors (0: none)
  bool any_errors = false;  // some run had errors, disconnects or decode failures
};

// Runs `config` once per count (in the order given), printing a line per run to `out`.
SweepResult run_sweep(LoadConfig config, const std::vector<int>& counts, double limit_ms,
                      std::ostream& progress, std::ostream& out);

}  // namespace vox::loadtest
