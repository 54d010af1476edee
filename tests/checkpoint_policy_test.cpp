#include "server/pipeline/checkpoint_policy.hpp"

#include <gtest/gtest.h>

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;
using Clock = CheckpointPolicy::Clock;

const CheckpointLimits kLimits{.interval = 10s,
                               .max_unsaved_chunks = 100,
                               .max_unsaved_edits = 1000,
                               .max_log_tail = 2000,
                               .retry = 5s};

TEST(CheckpointPolicy, NothingUnsavedIsNeverDue) {
  const Clock::time_point t0{};
  CheckpointPolicy p(kLimits, t0);
  EXPECT_FALSE(p.due(t0 + 1h, 0, 0));
}

// Edits that changed no chunk (an explosion in the air) are in the log all the same: a
// checkpoint of no chunks trims them, or a client could grow the log without end.
TEST(CheckpointPolicy, EditsThatChangedNothingAreCheckpointedToo) {
  const Clock::time_point t0{};
  CheckpointPolicy p(kLimits, t0);
  EXPECT_TRUE(p.due(t0 + 10s, 0, 1));
  EXPECT_TRUE(p.due(t0 + 1s, 0, 1000));
}

TEST(CheckpointPolicy, DueAfterTheIntervalOrAtABound) {
  const Clock::time_point t0{};
  CheckpointPolicy p(kLimits, t0);
  EXPECT_FALSE(p.due(t0 + 9s, 99, 999));
  EXPECT_TRUE(p.due(t0 + 10s, 1, 1));
  EXPECT_TRUE(p.due(t0 + 1s, 100, 1));   // too many chunks to wait
  EXPECT_TRUE(p.due(t0 + 1s, 1, 1000));  // the log grew too long
}

TEST(CheckpointPolicy, OneAtATimeAndTheIntervalCountsFromTheStart) {
  const Clock::time_point t0{};
  CheckpointPolicy p(kLimits, t0);
  p.started(t0 + 10s);
  EXPECT_TRUE(p.in_flight());
  EXPECT_FALSE(p.due(t0 + 11s, 500, 5000));
  p.finished(t0 + 12s, true);
  EXPECT_FALSE(p.due(t0 + 19s, 1, 1));
  EXPECT_TRUE(p.due(t0 + 20s, 1, 1));
}

TEST(CheckpointPolicy, AFailedCheckpointRestsTheStore) {
  const Clock::time_point t0{};
  CheckpointPolicy p(kLimits, t0);
  p.started(t0 + 10s);
  p.finished(t0 + 11s, false);
  EXPECT_FALSE(p.due(t0 + 15s, 500, 5000));  // bounds reached, but resting
  EXPECT_TRUE(p.due(t0 + 16s, 500, 5000));
}

// A flood of 7,000 edits/s outran the checkpoints and grew the log to 80,791 edits (a
// restart replayed them for 8.9 s): past the bound, edits are held back.
TEST(CheckpointPolicy, TheLogTailIsFullAtItsBound) {
  CheckpointPolicy p(kLimits, Clock::time_point{});
  EXPECT_FALSE(p.log_full(1999));
  EXPECT_TRUE(p.log_full(2000));
}

// A bound on the tail below the edit bound still makes a checkpoint due (or edits would be
// held back until the interval).
TEST(CheckpointPolicy, AFullLogTailMakesACheckpointDue) {
  const Clock::time_point t0{};
  CheckpointLimits limits = kLimits;
  limits.max_log_tail = 50;
  CheckpointPolicy p(limits, t0);
  EXPECT_FALSE(p.due(t0 + 1s, 1, 49));
  EXPECT_TRUE(p.due(t0 + 1s, 1, 50));
}

}  // namespace
}  // namespace vox::pipeline

namespace vox::pipeline {
namespace {

TEST(LogRetention, ACheckpointTrimsAllOnlyTheEditsBeforeTheWindowOrNone) {
  const auto now = std::chrono::system_clock::time_point(std::chrono::hours(1000));
  const int64_t now_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count();
  const store::LogTrim all = LogRetention{}.trim(42, now);
  EXPECT_EQ(all.through, 42u);
  EXPECT_EQ(all.accepted_before_ms, std::numeric_limits<int64_t>::max());
  const store::LogTrim window = LogRetention{.window = std::chrono::hours(24 * 7)}.trim(42, now);
  EXPECT_EQ(window.through, 42u);
  EXPECT_EQ(window.accepted_before_ms, now_ms - 7 * 24 * 3600 * 1000ll);
  EXPECT_EQ(window.stamps_until_ms, now_ms + 24 * 3600 * 1000ll);
  const LogRetention keep_all{.keep_all = true, .window = std::chrono::hours(1)};
  EXPECT_EQ(keep_all.trim(42, now).through, 0u);
}

}  // namespace
}  // namespace vox::pipeline
