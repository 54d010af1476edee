// When the pipeline writes a checkpoint of the chunks its edits changed: a pure policy
// (no clock, no I/O), so it is unit-tested alone. A checkpoint is due when there is
// something unsaved (a chunk, or an edit in the log) and one of three bounds is reached: time since
// the last one (what a restart must replay stays short), unsaved chunks (what a checkpoint copies
// and writes stays bounded), or logged edits since the last one (the log stays short). One at a
// time; after a failure the store rests `retry` before the next try. And a hard bound on the
// log's tail (the edits no finished checkpoint covers, which a restart replays): past it,
// edits are held back until a checkpoint trims the log, so no flood makes a restart slow.
// Pipeline thread only.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>

#include "server/store/world_store.hpp"

namespace vox::pipeline {

struct CheckpointLimits {
  std::chrono::milliseconds interval{std::chrono::seconds(10)};
  size_t max_unsaved_chunks = 2048;
  uint64_t max_unsaved_edits = 20000;
  // Edits the log may hold past the last finished checkpoint (in flight ones included);
  // a checkpoint is due by then whatever max_unsaved_edits says.
  uint64_t max_log_tail = 40000;
  std::chrono::milliseconds retry{std::chrono::seconds(5)};
};

// How much of the log checkpoints keep: all of it, or the edits of the last `window`.
struct LogRetention {
  bool keep_all = false;
  std::chrono::milliseconds window{0};
  // What a checkpoint through `seq` written at `now` deletes.
  store::LogTrim trim(uint64_t seq, std::chrono::system_clock::time_point now) const {
    if (keep_all) return {0};
    if (window.count() <= 0) return {seq};
    const auto ms = [](std::chrono::system_clock::time_point t) {
      return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
    };
    // A stamp more than a day ahead is a clock's mistake: it holds nothing back.
    return {seq, ms(now - window), ms(now + std::chrono::hours(24))};
  }
};

class CheckpointPolicy {
 public:
  using Clock = std::chrono::steady_clock;

  CheckpointPolicy(CheckpointLimits limits, Clock::time_point now)
      : limits_(checked(limits)), last_(now), not_before_(now) {}

  // `unsaved_edits`: accepted since the last checkpoint, whether or not they changed a
  // chunk (one that changed nothing is in the log all the same, and is trimmed by one).
  bool due(Clock::time_point now, size_t unsaved_chunks, uint64_t unsaved_edits) const {
    if (in_flight_ || (unsaved_chunks == 0 && unsaved_edits == 0) || now < not_before_)
      return false;
    return now - last_ >= limits_.interval || unsaved_chunks >= limits_.max_unsaved_chunks ||
           unsaved_edits >= std::min(limits_.max_unsaved_edits, limits_.max_log_tail);
  }
  // `log_tail`: edits logged (or being appended) that no finished checkpoint covers. Full:
  // the next edit is refused.
  bool log_full(uint64_t log_tail) const { return log_tail >= limits_.max_log_tail; }
  bool in_flight() const { return in_flight_; }
  void started(Clock::time_point now) {
    in_flight_ = true;
    last_ = now;
  }
  void finished(Clock::time_point now, bool ok) {
    in_flight_ = false;
    if (!ok) not_before_ = now + limits_.retry;
  }

 private:
  static CheckpointLimits checked(CheckpointLimits l) {
    l.max_log_tail = std::max<uint64_t>(l.max_log_tail, 1);  // 0 would refuse every edit
    return l;
  }
  const CheckpointLimits limits_;
  Clock::time_point last_;        // the last checkpoint started (or the policy was made)
  Clock::time_point not_before_;  // after a failure, the store rests until then
  bool in_flight_ = false;
};

}  // namespace vox::pipeline
