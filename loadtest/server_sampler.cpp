#include "loadtest/server_sampler.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace vox::loadtest {

std::string read_proc_file(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

double cpu_percent_between(std::optional<uint64_t> now, std::optional<uint64_t> before,
                           double seconds) {
  static const double kTicksPerSecond = static_cast<double>(::sysconf(_SC_CLK_TCK));
  if (!now || !before || *now < *before || !(seconds > 0))
    return std::numeric_limits<double>::quiet_NaN();
  return 100.0 * static_cast<double>(*now - *before) / kTicksPerSecond / seconds;
}

namespace {

std::string_view next_field(std::string_view& line) {
  const size_t start = line.find_first_not_of(" \t");
  if (start == std::string_view::npos) {
    line = {};
    return {};
  }
  line.remove_prefix(start);
  const size_t end = std::min(line.find_first_of(" \t"), line.size());
  const std::string_view field = line.substr(0, end);
  line.remove_prefix(end);
  return field;
}

template <class T>
std::optional<T> number(std::string_view text, int base) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace

std::optional<uint64_t> parse_vm_rss_kib(std::string_view status) {
  constexpr std::string_view kKey = "VmRSS:";
  for (size_t at = 0; at < status.size();) {
    const size_t end = std::min(status.find('\n', at), status.size());
    std::string_view line = status.substr(at, end - at);
    at = end + 1;
    if (line.substr(0, kKey.size()) != kKey) continue;
    line.remove_prefix(kKey.size());
    const auto value = number<uint64_t>(next_field(line), 10);
    if (value && next_field(line) == "kB") return value;
    return std::nullopt;
  }
  return std::nullopt;
}

std::optional<uint64_t> parse_cpu_ticks(std::string_view stat) {
  const size_t close = stat.rfind(')');
  if (close == std::string_view::npos) return std::nullopt;
  std::string_view rest = stat.substr(close + 1);
  // Fields 3 (state) onwards; utime and stime are fields 14 and 15 (proc(5)).
  std::array<std::string_view, 13> f;
  for (auto& field : f) field = next_field(rest);
  const auto utime = number<uint64_t>(f[11], 10), stime = number<uint64_t>(f[12], 10);
  if (!utime || !stime) return std::nullopt;
  return *utime + *stime;
}

// Lines: "sl local_address rem_address st ... uid timeout inode ...", the local address
// as HEXADDR:HEXPORT and st 0A for LISTEN (see proc(5)).
std::optional<uint64_t> find_listening_inode(std::string_view text, uint16_t port) {
  for (size_t at = text.find('\n'); at != std::string_view::npos && at < text.size();) {
    const size_t end = std::min(text.find('\n', at + 1), text.size());
    std::string_view line = text.substr(at + 1, end - at - 1);
    at = end;
    std::array<std::string_view, 10> f;
    for (auto& field : f) field = next_field(line);
    const size_t colon = f[1].rfind(':');
    if (colon == std::string_view::npos || f[3] != "0A") continue;
    if (number<uint16_t>(f[1].substr(colon + 1), 16) != port) continue;
    if (auto inode = number<uint64_t>(f[9], 10); inode && *inode != 0) return inode;
  }
  return std::nullopt;
}

std::optional<int> find_listening_pid(uint16_t port) {
  std::optional<uint64_t> inode;
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    if ((inode = find_listening_inode(read_proc_file(table), port))) break;
  }
  if (!inode) return std::nullopt;
  const std::string target = "socket:[" + std::to_string(*inode) + "]";
  namespace fs = std::filesystem;
  try {  // processes come and go while we look: any error means "not found"
    std::error_code ec;
    for (const auto& proc : fs::directory_iterator("/proc", ec)) {
      const auto pid = number<int>(proc.path().filename().string(), 10);
      if (!pid) continue;
      std::error_code fd_ec;  // other users' processes: permission denied, skipped
      for (const auto& fd : fs::directory_iterator(proc.path() / "fd", fd_ec)) {
        std::error_code link_ec;
        if (fs::read_symlink(fd.path(), link_ec).string() == target) return pid;
      }
    }
  } catch (const fs::filesystem_error&) {
  }
  return std::nullopt;
}

void ServerSampler::sample() {
  if (pid_ <= 0 || kib_.size() >= kMaxSamples) return;
  const std::string proc = "/proc/" + std::to_string(pid_);
  const auto kib = parse_vm_rss_kib(read_proc_file(proc + "/status"));
  if (!kib) return;
  kib_.push_back(static_cast<double>(*kib));
  const auto ticks = parse_cpu_ticks(read_proc_file(proc + "/stat"));
  const double at_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  if (kib_.size() > 1)  // one CPU figure per second after the first, NaN when unknown
    cpu_percent_.push_back(cpu_percent_between(ticks, last_ticks_, at_s - last_at_s_));
  if (ticks) {
    last_ticks_ = ticks;
    last_at_s_ = at_s;
  }
}

}  // namespace vox::loadtest
