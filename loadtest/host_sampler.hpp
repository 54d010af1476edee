// The load tester's own CPU and the host's stolen CPU, once a second: a slow second is
// the server's only when neither the tester (its players share the machine) nor the
// hypervisor (steal time on a shared VM) took the cores. Linux only, best effort: what
// cannot be read is NaN.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace vox::loadtest {

// Steal ticks (the 8th number of the aggregate "cpu " line of /proc/stat), summed over
// every CPU; nullopt when the line is missing or short.
std::optional<uint64_t> parse_steal_ticks(std::string_view proc_stat);

class HostSampler {
 public:
  // Main thread only, like every member. The first call sets the baseline; each later one
  // adds one figure to each series (NaN when unreadable), for the second since the last.
  void sample();
  // This process's CPU (utime + stime) per second, in percent of one core.
  const std::vector<double>& tester_cpu_percent() const { return tester_; }
  // CPU the hypervisor gave to others while this VM wanted it, in percent of one core.
  const std::vector<double>& steal_percent() const { return steal_; }

 private:
  static constexpr size_t kMaxSamples = 1 << 16;
  std::vector<double> tester_, steal_;
  std::optional<uint64_t> last_tester_, last_steal_;
  std::optional<double> last_at_s_;
};

}  // namespace vox::loadtest
