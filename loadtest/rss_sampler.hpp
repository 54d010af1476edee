// voxeld's resident memory over a load test, read from /proc/PID/status once a second:
// attackers that make the server hold memory show up here even when no honest figure
// moves. Linux only; every step is best effort (no pid, no samples, no error).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vox::loadtest {

// "VmRSS:  123456 kB" in /proc/PID/status text, in KiB.
std::optional<uint64_t> parse_vm_rss_kib(std::string_view status);
// The inode of the socket listening on `port`, from /proc/net/tcp or /proc/net/tcp6 text.
std::optional<uint64_t> find_listening_inode(std::string_view proc_net_tcp, uint16_t port);
// The process listening on `port` of this machine: the listening socket's inode, then
// the /proc/*/fd link naming it. nullopt when not found or not ours to look at.
std::optional<int> find_listening_pid(uint16_t port);

class RssSampler {
 public:
  explicit RssSampler(int pid) : pid_(pid) {}
  int pid() const { return pid_; }
  // Reads VmRSS now and keeps it (at most kMaxSamples, one a second is ~18 hours);
  // a process gone or unreadable adds nothing. Main thread only, like every member.
  void sample();
  const std::vector<double>& kib() const { return kib_; }

 private:
  static constexpr size_t kMaxSamples = 1 << 16;
  int pid_;
  std::vector<double> kib_;
};

}  // namespace vox::loadtest
