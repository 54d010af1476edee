#include "loadtest/host_sampler.hpp"

#include <charconv>
#include <chrono>

#include "loadtest/server_sampler.hpp"

namespace vox::loadtest {

std::optional<uint64_t> parse_steal_ticks(std::string_view text) {
  if (text.substr(0, 4) != "cpu ") return std::nullopt;
  text.remove_prefix(4);
  text = text.substr(0, text.find('\n'));
  // user nice system idle iowait irq softirq steal ...
  uint64_t value = 0;
  for (int field = 0; field < 8; ++field) {
    const size_t start = text.find_first_not_of(' ');
    if (start == std::string_view::npos) return std::nullopt;
    text.remove_prefix(start);
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc()) return std::nullopt;
    text.remove_prefix(static_cast<size_t>(end - text.data()));
  }
  return value;
}

void HostSampler::sample() {
  if (tester_.size() >= kMaxSamples) return;
  const auto tester = parse_cpu_ticks(read_proc_file("/proc/self/stat"));
  const auto steal = parse_steal_ticks(read_proc_file("/proc/stat"));
  const double at_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  if (last_at_s_) {
    tester_.push_back(cpu_percent_between(tester, last_tester_, at_s - *last_at_s_));
    steal_.push_back(cpu_percent_between(steal, last_steal_, at_s - *last_at_s_));
  }
  last_tester_ = tester;
  last_steal_ = steal;
  last_at_s_ = at_s;
}

}  // namespace vox::loadtest
