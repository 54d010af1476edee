#include "server/cluster/zone_replicas.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace vox::cluster {

namespace {

// Zones remembered as viewed, at most this many times those followed (the oldest go).
constexpr size_t kViewedPerFollowed = 4;

}  // namespace

ZoneReplicas::ZoneReplicas(NatsLink& nats, Config config, std::function<void()> wake)
    : nats_(nats), config_(std::move(config)), wake_(std::move(wake)) {}

ZoneReplicas::~ZoneReplicas() { stop(); }

void ZoneReplicas::stop() {
  stopped_ = true;
  std::vector<world::ZoneId> zones;
  for (const auto& [zone, f] : followers_) zones.push_back(zone);
  for (const world::ZoneId zone : zones) stop_follower(zone);
  followed_.store(0, std::memory_order_relaxed);
}

bool ZoneReplicas::viewing(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  const Clock::time_point now = Clock::now();
  auto& seen = viewed_[zone];
  // Not followed now (never viewed, or idle since), and a follower could start for it.
  const bool fresh = (seen == Clock::time_point{} || now - seen >= config_.idle) &&
                     followed_.load(std::memory_order_relaxed) < config_.max_zones;
  seen = now;
  const size_t bound = kViewedPerFollowed * config_.max_zones;
  if (viewed_.size() <= bound) return fresh;
  const auto oldest =
      std::min_element(viewed_.begin(), viewed_.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; });
  viewed_.erase(oldest);
  return fresh;
}

void ZoneReplicas::reconcile(const std::function<bool(world::ZoneId)>& held,
                             const std::function<uint64_t(world::ZoneId)>& applied) {
  if (stopped_) return;
  const Clock::time_point now = Clock::now();
  std::vector<std::pair<Clock::time_point, world::ZoneId>> wanted;  // newest first
  {
    std::lock_guard lock(mutex_);
    std::erase_if(viewed_, [&](const auto& v) { return now - v.second >= config_.idle; });
    for (const auto& [zone, at] : viewed_) wanted.emplace_back(at, zone);
  }
  std::sort(wanted.begin(), wanted.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::map<world::ZoneId, bool> keep;
  for (const auto& [at, zone] : wanted) {
    if (keep.size() >= config_.max_zones) break;
    if (!held(zone)) keep[zone] = true;
  }
  std::vector<world::ZoneId> drop;
  for (const auto& [zone, f] : followers_) {
    if (!keep.count(zone)) drop.push_back(zone);
  }
  for (const world::ZoneId zone : drop) stop_follower(zone);
  followed_.store(followers_.size(), std::memory_order_relaxed);
  for (const auto& entry : keep) {
    const world::ZoneId zone = entry.first;  // captured below (not a structured binding)
    if (followers_.count(zone)) continue;
    {
      std::lock_guard lock(mutex_);
      stopping_.erase(zone);
      waiting_[zone];  // give_back finds it while followed
    }
    try {
      ZoneFollower::Config fc{.world = config_.world,
                              .zone = zone,
                              .uri = config_.uri,
                              .node = config_.node,
                              .applied = applied(zone)};
      followers_[zone] =
          std::make_unique<ZoneFollower>(nats_, fc, [this, zone](const store::ZoneRecord& r) {
            std::unique_lock lock(mutex_);
            // The pipeline takes them; a follower being stopped does not wait.
            taken_.wait(lock, [&] {
              return waiting_[zone].size() < config_.max_waiting || stopping_[zone];
            });
            if (stopping_[zone]) return;
            waiting_[zone].push_back(r);
            lock.unlock();
            wake_();
          });
      {
        std::lock_guard lock(mutex_);
        started_.insert(zone);
      }
      wake_();
    } catch (const std::exception& e) {
      if (now - warned_at_ >= std::chrono::seconds(10)) {  // at most one line per 10 s
        warned_at_ = now;
        spdlog::warn("cluster: cannot follow zone ({}, {}) now: {} (tried again each round)",
                     zone.x, zone.z, e.what());
      }
    }
  }
  followed_.store(followers_.size(), std::memory_order_relaxed);
}

void ZoneReplicas::stop_follower(world::ZoneId zone) {
  {
    std::lock_guard lock(mutex_);
    stopping_[zone] = true;
  }
  taken_.notify_all();
  followers_.erase(zone);  // joins its thread
  std::lock_guard lock(mutex_);
  waiting_.erase(zone);  // following again reads from the last record applied
  stopping_.erase(zone);
  started_.erase(zone);
}

std::vector<world::ZoneId> ZoneReplicas::take_started() {
  std::lock_guard lock(mutex_);
  std::vector<world::ZoneId> out(started_.begin(), started_.end());
  started_.clear();
  return out;
}

void ZoneReplicas::started_again(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  if (waiting_.count(zone)) started_.insert(zone);  // still followed
}

std::optional<ZoneReplicas::Taken> ZoneReplicas::take(
    size_t max, const std::function<bool(world::ZoneId)>& held,
    const std::function<uint64_t(world::ZoneId)>& applied) {
  std::optional<Taken> out;
  {
    std::lock_guard lock(mutex_);
    // Zones take turns: from the one after the zone taken last, around.
    auto it = taken_last_ ? waiting_.upper_bound(*taken_last_) : waiting_.begin();
    for (size_t n = waiting_.size(); n > 0 && !out; --n, ++it) {
      if (it == waiting_.end()) it = waiting_.begin();
      std::deque<store::ZoneRecord>& q = it->second;
      if (held(it->first)) q.clear();
      const uint64_t done = applied(it->first);
      // Anywhere in the queue (records given back sit before later ones): applied already.
      std::erase_if(q, [done](const store::ZoneRecord& r) { return r.seq <= done; });
      if (q.empty()) continue;
      out.emplace();
      out->zone = it->first;
      taken_last_ = it->first;
      while (!q.empty() && out->records.size() < max) {
        out->records.push_back(std::move(q.front()));
        q.pop_front();
      }
    }
  }
  if (out) taken_.notify_all();
  return out;
}

void ZoneReplicas::give_back(world::ZoneId zone, std::vector<store::ZoneRecord> records) {
  std::lock_guard lock(mutex_);
  const auto it = waiting_.find(zone);
  if (it == waiting_.end()) return;  // no longer followed
  std::deque<store::ZoneRecord>& q = it->second;
  q.insert(q.begin(), std::make_move_iterator(records.begin()),
           std::make_move_iterator(records.end()));
  // In sequence order, each once: the follower queued later ones (and maybe the same ones,
  // when the pipeline had read them from the log) meanwhile. Two records of one sequence
  // number are one record, so their order does not matter (and no std::stable_sort: its
  // temporary buffer trips clang 14's AddressSanitizer, as it did in options/).
  std::sort(q.begin(), q.end(),
            [](const store::ZoneRecord& a, const store::ZoneRecord& b) { return a.seq < b.seq; });
  q.erase(std::unique(q.begin(), q.end(),
                      [](const store::ZoneRecord& a, const store::ZoneRecord& b) {
                        return a.seq == b.seq;
                      }),
          q.end());
}

bool ZoneReplicas::following(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  return waiting_.count(zone) > 0;
}

bool ZoneReplicas::viewed_lately(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = viewed_.find(zone);
  return it != viewed_.end() && Clock::now() - it->second < config_.idle;
}

bool ZoneReplicas::waiting() const {
  std::lock_guard lock(mutex_);
  if (!started_.empty()) return true;
  for (const auto& [zone, q] : waiting_) {
    if (!q.empty()) return true;
  }
  return false;
}

}  // namespace vox::cluster
