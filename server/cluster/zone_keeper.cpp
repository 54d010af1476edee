#include "server/cluster/zone_keeper.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "server/cluster/zone_plan.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/thread_name.hpp"

namespace vox::cluster {

struct ZoneKeeper::Leases {
  store::ZoneLeases db;
};

ZoneKeeper::ZoneKeeper(Config config, Events events)
    : config_(std::move(config)),
      events_(std::move(events)),
      leases_(new Leases{store::ZoneLeases(config_.uri, config_.node, config_.lease)}) {
  thread_ = named_thread("vox-zones", [this] { run(); });
}

ZoneKeeper::~ZoneKeeper() { stop(false); }

bool ZoneKeeper::want(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  if (interest_.contains(zone)) return true;
  if (interest_.size() >= config_.max_zones) return false;
  interest_.insert(zone);
  asked_ = true;
  wake_.notify_one();
  return true;
}

void ZoneKeeper::poke() {
  std::lock_guard lock(mutex_);
  asked_ = true;
  wake_.notify_one();
}

std::optional<uint64_t> ZoneKeeper::epoch_of(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = held_.find(zone);
  return it == held_.end() ? std::nullopt : std::optional<uint64_t>(it->second.epoch);
}

size_t ZoneKeeper::held_count() const {
  std::lock_guard lock(mutex_);
  return held_.size();
}

void ZoneKeeper::stop(bool release) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
    release_ = release;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void ZoneKeeper::run() {
  const auto period = config_.lease / 3;
  // Rounds asked for early (a zone wanted, a poke) come at most this often: a round
  // renews every held zone in the database.
  const auto least_gap = std::max<std::chrono::milliseconds>(config_.lease / 30, kLeastGap);
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    const Clock::time_point started = Clock::now();
    lock.unlock();
    round();
    if (events_.round) events_.round(leases_->db);
    lock.lock();
    // Woken early by a stop or a zone asked for. While another process holds the node id,
    // sooner: a restarted node takes its id (and zones) back as soon as its earlier run's
    // heartbeat has run out.
    wake_.wait_for(lock, shadowed_ ? least_gap * 3 : period, [&] { return stopping_ || asked_; });
    wake_.wait_until(lock, started + least_gap, [&] { return stopping_; });
    asked_ = false;
  }
  if (!release_) return;
  const std::map<world::ZoneId, Held> held = std::move(held_);
  held_.clear();
  lock.unlock();
  try {
    leases_->db.leave();  // out of the live list first: nobody hands a zone back to it
  } catch (const store::StoreError& e) {
    spdlog::warn("zones: node {} could not leave the live list: {}", config_.node, e.what());
  }
  for (const auto& [zone, h] : held) {
    if (events_.lost) events_.lost(zone, h.epoch);
    try {
      leases_->db.release(zone, h.epoch);
      if (events_.handed_off) events_.handed_off(zone);  // a graceful stop hands it on too
    } catch (const store::StoreError& e) {
      spdlog::warn("zones: could not release zone ({}, {}): {}", zone.x, zone.z, e.what());
    }
  }
}

std::optional<std::string> ZoneKeeper::unhealthy() const {
  if (shadowed_now_) return "another live process runs as node " + config_.node;
  const Clock::rep ok = round_ok_at_.load();
  const auto since = Clock::now() - Clock::time_point(Clock::duration(ok));
  // Rounds come every lease / 3: a lease and a half without one is an outage.
  if (ok == 0 || since > config_.lease + config_.lease / 2) {
    return "node " + config_.node + " has not reached the cluster's database" +
           (ok == 0
                ? std::string(" yet")
                : " for " +
                      std::to_string(
                          std::chrono::duration_cast<std::chrono::milliseconds>(since).count()) +
                      " ms");
  }
  return std::nullopt;
}

// One ownership round (the keeper thread). The database is called without the lock.
void ZoneKeeper::round() {
  std::set<world::ZoneId> held_zones, interest;
  std::map<world::ZoneId, Held> held;
  {
    std::lock_guard lock(mutex_);
    held = held_;
    interest = interest_;
  }
  for (const auto& [zone, h] : held) held_zones.insert(zone);
  const auto lose = [&](world::ZoneId zone, uint64_t epoch, const char* why) {
    {
      std::lock_guard lock(mutex_);
      held_.erase(zone);
    }
    spdlog::info("zones: node {} lost zone ({}, {}) at epoch {}: {}", config_.node, zone.x, zone.z,
                 epoch, why);
    if (events_.lost) events_.lost(zone, epoch);
  };
  const Clock::time_point start = Clock::now();
  try {
    store::ZoneLeases& db = leases_->db;
    if (const std::optional<std::string> other = db.heartbeat(config_.address)) {
      // Another process runs as this node: it takes and renews the zones, this one holds
      // none (edits here are forwarded) until that one's heartbeat runs out. Within two
      // leases that is most likely this node's earlier run (killed, restarted): no error.
      if (!shadowed_) shadowed_since_ = start;
      const bool long_ago = start - shadowed_since_ >= 2 * config_.lease;
      if (!shadowed_) {
        spdlog::warn(
            "zones: node id {} is alive at {} (an earlier run of this node, or another process "
            "given the same id): this one takes no zones until its heartbeat runs out",
            config_.node, *other);
      } else if (long_ago && (!shadow_logged_ || start - *shadow_logged_ >= kShadowLogEvery)) {
        spdlog::error(
            "zones: another process runs as node {} (at {}); two processes must not share a "
            "node id: this one takes no zones while that one lives",
            config_.node, *other);
        shadow_logged_ = start;
      }
      shadowed_ = true;
      shadowed_now_ = true;
      for (const auto& [zone, h] : held) lose(zone, h.epoch, "another process runs as this node");
      return;
    }
    shadowed_now_ = false;
    round_ok_at_ = Clock::now().time_since_epoch().count();  // the heartbeat reached it
    if (shadowed_) spdlog::info("zones: node id {} is this process's now", config_.node);
    shadowed_ = false;
    shadow_logged_.reset();
    const ZonePlan plan = plan_zones(held_zones, interest, db.live_nodes(), config_.node);
    for (const world::ZoneId zone : plan.renew) {
      const uint64_t epoch = held.at(zone).epoch;
      if (db.renew(zone, epoch)) {
        std::lock_guard lock(mutex_);
        if (auto it = held_.find(zone); it != held_.end()) it->second.renewed = start;
      } else {
        lose(zone, epoch, "another node took it");
      }
    }
    // A graceful hand-off: no more edits here, a moment for the appends in flight to land
    // (the lease is still this node's), then released.
    if (!plan.hand_off.empty() && events_.leaving) {
      for (const world::ZoneId zone : plan.hand_off) events_.leaving(zone, held.at(zone).epoch);
      std::this_thread::sleep_for(std::min(config_.lease / 10, std::chrono::milliseconds(50)));
    }
    for (const world::ZoneId zone : plan.hand_off) {
      const uint64_t epoch = held.at(zone).epoch;
      lose(zone, epoch, "handed off to the node that now ranks first");
      db.release(zone, epoch);
      if (events_.handed_off) events_.handed_off(zone);
    }
    for (const world::ZoneId zone : plan.take) {
      if (const auto epoch = db.acquire(zone)) {
        {
          std::lock_guard lock(mutex_);
          held_[zone] = Held{*epoch, start};
        }
        spdlog::info("zones: node {} took zone ({}, {}) at epoch {}", config_.node, zone.x, zone.z,
                     *epoch);
        if (events_.taken) events_.taken(zone, *epoch);
      }
    }
  } catch (const store::StoreError& e) {
    spdlog::warn("zones: node {}: {}", config_.node, e.what());
  }
  // Not renewed for a whole lease (the database out of reach): no longer provably ours.
  const Clock::time_point now = Clock::now();
  std::vector<std::pair<world::ZoneId, uint64_t>> expired;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [zone, h] : held_) {
      if (now - h.renewed >= config_.lease) expired.emplace_back(zone, h.epoch);
    }
  }
  for (const auto& [zone, epoch] : expired) lose(zone, epoch, "its lease ran out unrenewed");
}

}  // namespace vox::cluster
