#include "loadtest/sweep.hpp"

#include <algorithm>
#include <charconv>
#include <string>

namespace vox::loadtest {

proto::Result<std::vector<int>> parse_sweep_counts(std::string_view text) {
  constexpr size_t kMaxRuns = 64;
  std::vector<int> counts;
  size_t start = 0;
  for (;;) {
    const size_t comma = text.find(',', start);
    const std::string_view item =
        text.substr(start, comma == std::string_view::npos ? text.npos : comma - start);
    int n = 0;
    const auto [end, ec] = std::from_chars(item.data(), item.data() + item.size(), n);
    if (item.empty() || ec != std::errc() || end != item.data() + item.size() || n < 1 ||
        n > 10000) {
      std::string message = "not a player count 1..10000 (want N1,N2,...): '";
      message.append(item).append("'");
      return proto::Error{message};
    }
    counts.push_back(n);
    if (counts.size() > kMaxRuns) return proto::Error{"more than 64 player counts"};
    if (comma == std::string_view::npos) return counts;
    start = comma + 1;
  }
}

SweepResult run_sweep(LoadConfig config, const std::vector<int>& counts, double limit_ms,
                      std::ostream& progress, std::ostream& out) {
  SweepResult result;
  for (const int n : counts) {
    config.players = n;
    LoadTest run(config);
    const LoadStats stats = run.run(progress);
    std::vector<double> ms;
    for (const auto& s : stats.edit_to_delta) ms.push_back(s.ms);
    const double p99 = percentiles(ms).p99;
    const uint64_t errors = stats.error_count() + stats.disconnect_count() + stats.decode_failures;
    result.points.push_back({n, p99, errors});
    result.any_errors = result.any_errors || errors > 0;
    out << "players " << n << ": edit->delta p99 " << p99 << " ms, errors " << errors << "\n";
    if (p99 <= limit_ms && errors == 0) result.best = std::max(result.best, n);
  }
  out << "largest player count with p99 <= " << limit_ms << " ms and no errors: " << result.best
      << "\n";
  return result;
}

}  // namespace vox::loadtest
