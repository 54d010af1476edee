#include "server/cluster/zone_publisher.hpp"

#include <spdlog/spdlog.h>

#include "server/cluster/zone_wire.hpp"

namespace vox::cluster {

ZonePublisher::ZonePublisher(NatsLink& nats, store::ZoneLeases& log, std::string world)
    : nats_(nats), log_(log), world_(std::move(world)) {
  if (!valid_world_name(world_))
    throw ClusterError("a world name for subjects: letters, digits, '-' and '_' (1 to 64)");
}

void ZonePublisher::adopt(world::ZoneId zone, uint64_t last_seq) {
  std::lock_guard lock(mutex_);
  last_[zone] = last_seq;
}

void ZonePublisher::forget(world::ZoneId zone) {
  std::lock_guard lock(mutex_);
  last_.erase(zone);
}

std::optional<uint64_t> ZonePublisher::last_seq(world::ZoneId zone) const {
  std::lock_guard lock(mutex_);
  const auto it = last_.find(zone);
  if (it == last_.end()) return std::nullopt;
  return it->second;
}

std::pair<uint64_t, uint64_t> ZonePublisher::commit(world::ZoneId zone, uint64_t epoch,
                                                    std::span<const std::vector<uint8_t>> payloads,
                                                    int64_t unix_ms) {
  Part part{zone, epoch, {}};
  for (const auto& p : payloads) part.records.push_back({0, unix_ms, p});
  commit(std::span<Part>(&part, 1));
  if (part.records.empty()) {
    const uint64_t last = last_seq(zone).value_or(0);
    return {last + 1, last};
  }
  return {part.records.front().seq, part.records.back().seq};
}

uint64_t ZonePublisher::commit(std::span<Part> parts, const std::function<void(uint64_t)>& durable,
                               const store::RegionsAt* regions) {
  std::vector<store::ZoneAppend> appends;
  {
    std::lock_guard lock(mutex_);
    for (Part& part : parts) {
      const auto it = last_.find(part.zone);
      if (it == last_.end())
        throw store::FencedError("zone (" + std::to_string(part.zone.x) + ", " +
                                     std::to_string(part.zone.z) +
                                     ") is not this node's (lost, or never adopted)",
                                 part.zone);
      uint64_t seq = it->second;
      for (store::ZoneRecord& r : part.records) r.seq = ++seq;
    }
  }
  for (const Part& part : parts)
    appends.push_back({part.zone, part.epoch, part.records, part.pending});
  const uint64_t version = log_.append(appends, regions);  // throws: nothing published
  {
    std::lock_guard lock(mutex_);
    for (const Part& part : parts) {
      // A zone forgotten meanwhile (lost) stays forgotten.
      if (const auto it = last_.find(part.zone); it != last_.end() && !part.records.empty())
        it->second = part.records.back().seq;
    }
  }
  if (durable) durable(version);
  for (const Part& part : parts) {
    const std::string subject = zone_subject(world_, part.zone, "rec");
    for (const store::ZoneRecord& r : part.records)
      publish(subject, encode_zone_record(part.zone, r));
  }
  if (regions && regions->write) publish(regions_subject(world_), encode_regions_version(version));
  return version;
}

void ZonePublisher::heartbeat() {
  std::vector<std::pair<world::ZoneId, uint64_t>> beats;
  {
    std::lock_guard lock(mutex_);
    beats.assign(last_.begin(), last_.end());
  }
  for (const auto& [zone, last] : beats)
    publish(zone_subject(world_, zone, "hb"), encode_zone_heartbeat(zone, last));
}

void ZonePublisher::publish(const std::string& subject, std::span<const uint8_t> bytes) {
  try {
    nats_.publish(subject, bytes);
  } catch (const ClusterError& e) {
    const uint64_t failures = ++publish_failures_;
    if (failures % 1000 == 1)  // one line per thousand failures
      spdlog::warn("zones: {} (followers read the log) [{} failed publishes so far]", e.what(),
                   failures);
  }
}

}  // namespace vox::cluster
