// A token bucket: `rate` tokens per second up to `burst`. Pure (the caller passes the
// time); used for each session's edit budget (tokens = samples an edit touches), its
// SetView rate and its message rate. Not synchronised: one owner (a session's strand).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>

namespace vox::net {

class TokenBucket {
 public:
  using Clock = std::chrono::steady_clock;

  // rate <= 0: unlimited. Starts full.
  TokenBucket(double rate, double burst, Clock::time_point now = Clock::now())
      : rate_(rate), burst_(std::max(burst, 0.0)), tokens_(burst_), at_(now) {}

  bool unlimited() const { return rate_ <= 0; }
  double rate() const { return rate_; }
  double burst() const { return burst_; }

  // Takes `cost` tokens if there are that many; otherwise takes nothing and returns how
  // long until there will be (a cost over the burst can never pass: max duration).
  // Zero duration means taken.
  std::chrono::milliseconds take(double cost, Clock::time_point now) {
    if (unlimited()) return std::chrono::milliseconds(0);
    refill(now);
    if (cost <= tokens_) {
      tokens_ -= cost;
      return std::chrono::milliseconds(0);
    }
    if (cost > burst_) return std::chrono::milliseconds::max();
    const double wait_s = (cost - tokens_) / rate_;
    return std::chrono::milliseconds(std::max<long long>(1, static_cast<long long>(std::ceil(wait_s * 1000))));
  }
  double tokens(Clock::time_point now) {
    refill(now);
    return tokens_;
  }

 private:
  void refill(Clock::time_point now) {
    if (now <= at_) return;
    tokens_ = std::min(burst_, tokens_ + rate_ * std::chrono::duration<double>(now - at_).count());
    at_ = now;
  }

  double rate_, burst_, tokens_;
  Clock::time_point at_;
};

}  // namespace vox::net
