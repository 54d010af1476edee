#include "server/cluster/zone_publisher.hpp"

#include <spdlog/spdlog.h>

#include "server/cluster/zone_wire.hpp"

namespace vox::cluster {

ZonePublisher::ZonePublisher(NatsLink& nats, store::ZoneLeases& log, std::string world)
    : nats_(nats), log_(log), world_(std::move(world)) {
  if (!valid_world_name(world_))
    throw ClusterError("a world name for subjects: letters, digits, '-' and '_' (1 to 64)");
}

std::pair<uint64_t, uint64_t> ZonePublisher::commit(world::ZoneId zone, uint64_t epoch,
                                                    std::span<const std::vector<uint8_t>> payloads,
                                                    int64_t unix_ms) {
  const auto it = last_.find(zone);
  if (it == last_.end())
    throw store::StoreError("zone (" + std::to_string(zone.x) + ", " + std::to_string(zone.z) +
                            ") is not this node's (never adopted)");
  std::vector<store::ZoneRecord> records;
  records.reserve(payloads.size());
  for (const auto& p : payloads) records.push_back({it->second + records.size() + 1, unix_ms, p});
  if (records.empty()) return {it->second + 1, it->second};
  log_.append(zone, epoch, records);  // throws: nothing published
  it->second = records.back().seq;
  const std::string subject = zone_subject(world_, zone, "rec");
  for (const store::ZoneRecord& r : records) publish(subject, encode_zone_record(zone, r));
  return {records.front().seq, records.back().seq};
}

void ZonePublisher::heartbeat() {
  for (const auto& [zone, last] : last_)
    publish(zone_subject(world_, zone, "hb"), encode_zone_heartbeat(zone, last));
}

void ZonePublisher::publish(const std::string& subject, std::span<const uint8_t> bytes) {
  try {
    nats_.publish(subject, bytes);
  } catch (const ClusterError& e) {
    if (publish_failures_++ % 1000 == 0)  // one line per thousand failures
      spdlog::warn("zones: {} (followers read the log) [{} failed publishes so far]", e.what(),
                   publish_failures_);
  }
}

}  // namespace vox::cluster
