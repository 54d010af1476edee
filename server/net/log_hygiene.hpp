// Log lines a client can cause: at most a few per second per kind (one for protocol
// errors), with a count of the ones suppressed meanwhile; and client strings escaped so
// they cannot forge lines.
#pragma once

#include <chrono>
#include <cstddef>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

namespace vox::net {

// Printable ASCII is kept (but backslash and quote); everything else, newlines and
// control characters included, becomes \xNN. At most `max_bytes` input bytes are shown.
std::string escape_for_log(std::string_view s, size_t max_bytes = 64);

// Pure policy: whether a line of `kind` may be written at `now`.
class LogRateLimit {
 public:
  using Clock = std::chrono::steady_clock;
  explicit LogRateLimit(Clock::duration interval = std::chrono::seconds(1)) : interval_(interval) {}
  // nullopt: suppress (counted). Otherwise write, mentioning the returned number of lines
  // of this kind suppressed since the last one written. At most `per_interval` lines of a
  // kind are written per interval.
  std::optional<size_t> allow(const std::string& kind, Clock::time_point now,
                              size_t per_interval = 1);

 private:
  struct Kind {
    Clock::time_point window{};  // start of the current interval
    size_t written = 0;          // lines written in it
    size_t suppressed = 0;
  };
  Clock::duration interval_;
  std::unordered_map<std::string, Kind> kinds_;  // bounded by the kinds the code names
};

// LogRateLimit behind a leaf mutex, shared by every session. Any thread.
class SharedLogRateLimit {
 public:
  std::optional<size_t> allow(const std::string& kind, size_t per_interval = 1) {
    std::lock_guard lock(mutex_);
    return limit_.allow(kind, LogRateLimit::Clock::now(), per_interval);
  }

 private:
  std::mutex mutex_;  // leaf lock
  LogRateLimit limit_;
};

}  // namespace vox::net
