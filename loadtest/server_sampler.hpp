// voxeld's resident memory and CPU over a load test, read from /proc/PID/status and
// /proc/PID/stat once a second: attackers that make the server hold memory, or a soak
// whose memory creeps, show up here even when no honest figure moves. Linux only; every
// step is best effort (no pid, no samples, no error).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vox::loadtest {

// "VmRSS:  123456 kB" in /proc/PID/status text, in KiB.
std::optional<uint64_t> parse_vm_rss_kib(std::string_view status);
// utime + stime, in clock ticks, from /proc/PID/stat text (the fields after the command
// name in parentheses, which may itself hold spaces and parentheses).
std::optional<uint64_t> parse_cpu_ticks(std::string_view stat);
// 100 * (now - before) clock ticks over `seconds`: percent of one core. NaN when either
// reading is missing, the ticks went back or no time passed.
double cpu_percent_between(std::optional<uint64_t> now, std::optional<uint64_t> before,
                           double seconds);
// A /proc file's whole text; empty when it cannot be read.
std::string read_proc_file(const std::string& path);
// The inode of the socket listening on `port`, from /proc/net/tcp or /proc/net/tcp6 text.
std::optional<uint64_t> find_listening_inode(std::string_view proc_net_tcp, uint16_t port);
// The process listening on `port` of this machine: the listening socket's inode, then
// the /proc/*/fd link naming it. nullopt when not found or not ours to look at.
std::optional<int> find_listening_pid(uint16_t port);

class ServerSampler {
 public:
  explicit ServerSampler(int pid) : pid_(pid) {}
  int pid() const { return pid_; }
  // Reads VmRSS and the CPU time used now and keeps them (at most kMaxSamples, one a
  // second is ~18 hours); a process gone or unreadable adds nothing. Main thread only,
  // like every member.
  void sample();
  const std::vector<double>& kib() const { return kib_; }
  // Per sample after the first: the CPU the server used since the one before, in percent
  // of one core (200 = two cores busy); NaN when /proc/PID/stat could not be read. One
  // element fewer than kib() (none before the second sample), so element i covers second i.
  const std::vector<double>& cpu_percent() const { return cpu_percent_; }

 private:
  static constexpr size_t kMaxSamples = 1 << 16;
  int pid_;
  std::vector<double> kib_, cpu_percent_;
  std::optional<uint64_t> last_ticks_;
  double last_at_s_ = 0;  // steady clock, when last_ticks_ was read
};

}  // namespace vox::loadtest
