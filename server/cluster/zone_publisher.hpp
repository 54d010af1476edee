// The owner's side of its zones' records (docs/CLUSTER.md): each batch is appended to the
// zone's log under the owner's epoch (ZoneLeases::append: FencedError once another node
// took the zone, and then nothing is published), then each record goes out on the zone's
// record subject — facts after commit only. heartbeat() publishes every held zone's last
// sequence number, so followers notice records lost on the way and read them from the
// log. A publish that fails (NATS down) is counted, never thrown: the log has the record.
//
// Threads: commit from one thread at a time (the node's appender); adopt, forget,
// last_seq and heartbeat from any (a leaf lock, never held across I/O).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "server/cluster/nats_link.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

class ZonePublisher {
 public:
  ZonePublisher(NatsLink& nats, store::ZoneLeases& log, std::string world);

  // A zone just taken: its records continue from the log's last (ZoneRow::last_seq).
  void adopt(world::ZoneId zone, uint64_t last_seq);
  void forget(world::ZoneId zone);  // lost or handed off
  // The zone's last record as far as this publisher knows (nullopt: not adopted).
  std::optional<uint64_t> last_seq(world::ZoneId zone) const;

  // One zone's part of a commit: its records' seq are set by commit.
  struct Part {
    world::ZoneId zone;
    uint64_t epoch = 0;
    std::vector<store::ZoneRecord> records;
    std::vector<store::ZonePending> pending;  // other zones' parts of its edits
  };
  // Appends every part in one transaction (all zones adopted, each at its epoch), durable
  // when it returns; runs `durable` with the regions' version after it (the caller notes the
  // records and the version as its own before anyone can hear of them), then publishes
  // them. With `regions`, the append is refused unless
  // the protected regions are at regions->version, and changes them by regions->write
  // (ZoneLeases::append), whose new version is then published on the regions' subject.
  // Returns the regions' version after it (0 without `regions`). Throws
  // store::FencedError (store::RegionsChangedError) or store::StoreError, having
  // published nothing.
  uint64_t commit(std::span<Part> parts, const std::function<void(uint64_t)>& durable = {},
                  const store::RegionsAt* regions = nullptr);

  // Appends `payloads` as the zone's next records at `epoch` (the zone must be adopted),
  // durable when it returns, then publishes them; returns the first and last seq. Throws
  // store::FencedError or store::StoreError, having published nothing.
  std::pair<uint64_t, uint64_t> commit(world::ZoneId zone, uint64_t epoch,
                                       std::span<const std::vector<uint8_t>> payloads,
                                       int64_t unix_ms);
  // Each adopted zone's last sequence number on its heartbeat subject.
  void heartbeat();

  uint64_t publish_failures() const { return publish_failures_; }

 private:
  void publish(const std::string& subject, std::span<const uint8_t> bytes);

  NatsLink& nats_;
  store::ZoneLeases& log_;
  const std::string world_;
  mutable std::mutex mutex_;                // guards last_
  std::map<world::ZoneId, uint64_t> last_;  // adopted zones' last seq (bounded by the zones held)
  std::atomic<uint64_t> publish_failures_{0};
};

}  // namespace vox::cluster
