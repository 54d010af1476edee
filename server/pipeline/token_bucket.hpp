// A token bucket: `rate` tokens per second up to `burst`. Pure (the caller passes the
// time); used for each session's edit budget (tokens = samples an edit touches), its
// SetView and message rates, and each view's load work in the BatchScheduler. Not
// synchronised: one owner (a session's strand, or the scheduler under its lock).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>

namespace vox::pipeline {

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
    const auto wait = wait_for(cost, now);
    if (wait.count() == 0 && !unlimited()) tokens_ -= cost;
    return wait;
  }
  // How long until `cost` tokens will be there (0: now); takes nothing.
  std::chrono::milliseconds wait_for(double cost, Clock::time_point now) {
    if (unlimited()) return std::chrono::milliseconds(0);
    refill(now);
    if (cost <= tokens_) return std::chrono::milliseconds(0);
    if (cost > burst_) return std::chrono::milliseconds::max();
    return std::chrono::milliseconds(
        std::max<long long>(1, static_cast<long long>(std::ceil((cost - tokens_) / rate_ * 1000))));
  }

  // Takes `cost` whatever the level: the bucket may go into debt, which later takes wait
  // for (work whose cost is known only once it is done).
  void charge(double cost, Clock::time_point now) {
    if (unlimited()) return;
    refill(now);
    tokens_ -= cost;
  }
  // New limits from `now` on; the tokens held are kept, up to the new burst.
  void set_limits(double rate, double burst, Clock::time_point now) {
    const bool was_unlimited = unlimited();
    refill(now);
    rate_ = rate;
    burst_ = std::max(burst, 0.0);
    tokens_ = was_unlimited ? burst_ : std::min(tokens_, burst_);  // unlimited held "all"
  }
  bool full(Clock::time_point now) {
    refill(now);
    return unlimited() || tokens_ >= burst_;
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

}  // namespace vox::pipeline
