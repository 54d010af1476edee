#include "server/cluster/zone_follower.hpp"

#include <spdlog/spdlog.h>

#include <vector>

#include "server/cluster/zone_wire.hpp"
#include "server/world/thread_name.hpp"

namespace vox::cluster {
namespace {

// Records held for their turn, by count and by payload bytes; more are read from the log.
constexpr size_t kMaxAhead = 10000;
constexpr size_t kMaxAheadBytes = size_t{16} << 20;
constexpr size_t kLogPage = 1000;  // records per log read

}  // namespace

ZoneFollower::ZoneFollower(NatsLink& nats, Config config, Apply apply)
    : nats_(nats),
      config_(std::move(config)),
      apply_(std::move(apply)),
      log_(config_.uri, config_.node, std::chrono::milliseconds(3000)) {
  if (!valid_world_name(config_.world))
    throw ClusterError("a world name for subjects: letters, digits, '-' and '_' (1 to 64)");
  applied_.store(config_.applied, std::memory_order_release);
  // Subscribed before the log is read: whatever commits meanwhile is either in the log
  // read or arrives here.
  const auto handler = [this](const NatsMessage& m) { on_message(m); };
  records_sub_ = nats_.subscribe(zone_subject(config_.world, config_.zone, "rec"), handler);
  try {
    heartbeat_sub_ = nats_.subscribe(zone_subject(config_.world, config_.zone, "hb"), handler);
  } catch (...) {
    nats_.unsubscribe(records_sub_);  // its handler would outlive this object
    throw;
  }
  nats_.flush(std::chrono::milliseconds(2000));
  thread_ = named_thread("vox-follow", [this] { run(); });
}

ZoneFollower::~ZoneFollower() {
  nats_.unsubscribe(records_sub_);  // waits for a handler in progress
  nats_.unsubscribe(heartbeat_sub_);
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void ZoneFollower::on_message(const NatsMessage& m) {
  auto message = decode_zone_message(m.data);
  if (!message || message->zone != config_.zone) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  std::lock_guard lock(mutex_);
  newest_ = std::max(newest_, message->record.seq);
  const size_t bytes = message->record.payload.size();
  if (!message->heartbeat && message->record.seq > applied() && ahead_.size() < kMaxAhead &&
      ahead_bytes_ + bytes <= kMaxAheadBytes &&
      ahead_.emplace(message->record.seq, std::move(message->record)).second)
    ahead_bytes_ += bytes;
  wake_.notify_one();
}

// Applies the log's records after applied_ (all of them when `through` is past the end).
ZoneFollower::Fill ZoneFollower::fill(uint64_t through) {
  while (applied() < through) {
    std::vector<store::ZoneRecord> page;
    try {
      page = log_.read_log(config_.zone, applied(), kLogPage);
    } catch (const store::StoreError& e) {
      spdlog::warn("zone ({}, {}): reading its log: {}", config_.zone.x, config_.zone.z, e.what());
      std::unique_lock lock(mutex_);  // retried on the next turn, not in a tight loop
      wake_.wait_for(lock, std::chrono::milliseconds(200), [&] { return stopping_; });
      return Fill::kFailed;
    }
    for (const store::ZoneRecord& r : page) {
      if (r.seq != applied() + 1) break;  // the log has no gaps; guard anyway
      apply_(r);
      applied_.store(r.seq, std::memory_order_release);
      filled_.fetch_add(1, std::memory_order_relaxed);
    }
    if (page.size() < kLogPage) return applied() >= through ? Fill::kReached : Fill::kShort;
  }
  return Fill::kReached;
}

void ZoneFollower::run() {
  // Where to start: after the zone's checkpoint when the replica should install it. Asked
  // until the database answers (from record 1 instead, a migrated zone, whose log starts
  // at 2, would wait for a record 1 for ever).
  for (;;) {
    try {
      const std::optional<store::ZoneRow> row = log_.read(config_.zone);
      if (row && checkpoint_first(applied(), row->checkpoint_seq))
        applied_.store(row->checkpoint_seq, std::memory_order_release);
      break;
    } catch (const store::StoreError&) {
      std::unique_lock lock(mutex_);
      if (wake_.wait_for(lock, std::chrono::seconds(1), [&] { return stopping_; })) return;
    }
  }
  fill(UINT64_MAX);  // what the replica lacks, up to the log's end
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    // Records in turn, applied outside the lock.
    while (!ahead_.empty() && ahead_.begin()->first <= applied() + 1) {
      auto node = ahead_.extract(ahead_.begin());
      ahead_bytes_ -= node.mapped().payload.size();
      if (node.key() != applied() + 1) continue;  // already applied (from the log)
      lock.unlock();
      apply_(node.mapped());
      applied_.store(node.key(), std::memory_order_release);
      lock.lock();
    }
    if (stopping_) break;
    if (newest_ > applied()) {
      // A gap: give NATS a moment to deliver the missing record, then read the log.
      const bool came = wake_.wait_for(lock, config_.gap_wait, [&] {
        return stopping_ || (!ahead_.empty() && ahead_.begin()->first == applied() + 1);
      });
      if (came || stopping_) continue;
      const uint64_t through = newest_;
      lock.unlock();
      const Fill filled = fill(through);
      lock.lock();
      // The log is read and ends short of what a message claimed: records are published
      // only after commit, so the claim was false. Forget it (counted), or the follower
      // would read the log every gap_wait for ever.
      if (filled == Fill::kShort && newest_ == through) {
        newest_ = applied();
        dropped_.fetch_add(1, std::memory_order_relaxed);
      }
      continue;
    }
    wake_.wait(lock, [&] { return stopping_ || newest_ > applied(); });
  }
}

}  // namespace vox::cluster
