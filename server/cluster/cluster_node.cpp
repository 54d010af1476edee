#include "server/cluster/cluster_node.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <climits>

#include "server/cluster/zone_wire.hpp"
#include "server/store/postgres_store.hpp"

namespace vox::cluster {

namespace {

// Records one catch-up read applies at most: the pipeline goes on between reads.
constexpr size_t kRecordsPerRead = 2000;

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

}  // namespace

ClusterNode::ClusterNode(ClusterConfig config, uint64_t seed)
    : config_(std::move(config)),
      nats_(config_.nats),
      append_db_(config_.database, config_.node, config_.lease),
      read_db_(config_.database, config_.node, config_.lease),
      publisher_(nats_, append_db_, config_.world),
      store_(table_, publisher_, config_.zone_chunks, seed,
             "cluster world " + config_.world + " (" + store::redact_uri(config_.database) + ")"),
      replicas_(nats_, {.world = config_.world, .uri = config_.database, .node = config_.node},
                [this] {
                  if (wake_) wake_();
                }) {
  const store::WorldSettings mine{config_.world, seed, config_.zone_chunks};
  const store::WorldSettings theirs = read_db_.settle_world(mine);
  if (theirs != mine) {
    throw ClusterError("the cluster's database holds world " + theirs.name + " (seed " +
                       std::to_string(theirs.seed) + ", zones of " +
                       std::to_string(theirs.zone_chunks) + " chunks); this node is set to " +
                       mine.name + " (seed " + std::to_string(mine.seed) + ", " +
                       std::to_string(mine.zone_chunks) + "): one world per database");
  }
}

ClusterNode::~ClusterNode() { stop(false); }

void ClusterNode::start(const std::string& address) {
  keeper_ = std::make_unique<ZoneKeeper>(
      ZoneKeeper::Config{.uri = config_.database,
                         .node = config_.node,
                         .address = address,
                         .lease = config_.lease},
      ZoneKeeper::Events{.taken = [this](world::ZoneId z, uint64_t epoch) { taken(z, epoch); },
                         .lost = [this](world::ZoneId z, uint64_t epoch) { lost(z, epoch); },
                         .round = [this] { round(); }});
  spdlog::info("cluster: node {} of world {} (zones of {} chunks, lease {} ms), NATS {}",
               config_.node, config_.world, config_.zone_chunks, config_.lease.count(),
               nats_.server());
}

void ClusterNode::stop(bool release) {
  if (keeper_) keeper_->stop(release);
}

void ClusterNode::taken(world::ZoneId zone, uint64_t epoch) {
  table_.taken(zone, epoch);  // the keeper logged it
  if (wake_) wake_();
}

void ClusterNode::lost(world::ZoneId zone, uint64_t epoch) {
  table_.lost(zone, epoch);  // likewise
  if (!table_.held(zone)) publisher_.forget(zone);
}

void ClusterNode::round() {
  publisher_.heartbeat();
  replicas_.reconcile([this](world::ZoneId z) { return table_.held(z); },
                      [this](world::ZoneId z) { return table_.applied(z); });
}

void ClusterNode::viewing(world::ChunkCoord center, int radius) {
  const int64_t r = std::clamp(radius, 0, 1 << 16);
  const auto voxel = [](int64_t chunk) {
    return static_cast<int32_t>(
        std::clamp<int64_t>(chunk * world::kChunkSize, INT32_MIN + 64, INT32_MAX - 64));
  };
  const world::VoxelBox box{{voxel(center.x - r), 0, voxel(center.z - r)},
                            {voxel(center.x + r), 0, voxel(center.z + r)}};
  // Views are at most a few dozen chunks across; the replicas bound what they remember.
  for (const world::ZoneId zone : world::zones_of(box, config_.zone_chunks))
    replicas_.viewing(zone);
}

bool ClusterNode::writable(const world::Edit& edit, const world::VoxelBox& box, std::string& why) {
  const std::vector<world::ZoneId> zones = world::zones_of(box, config_.zone_chunks);
  if (zones.size() > 1 && std::holds_alternative<world::Smooth>(edit)) {
    why = "a smooth across a zone border is not taken by a cluster yet";
    return false;
  }
  for (const world::ZoneId zone : zones) {
    if (table_.writable(zone)) continue;
    if (table_.held(zone)) {
      why = describe(zone) + " is being loaded on this node; retry shortly";
    } else {
      if (keeper_) keeper_->want(zone);
      why = describe(zone) +
            " is not held by this node: it is taken if this node ranks first for it, else "
            "edit it through the node that holds it";
    }
    return false;
  }
  return true;
}

std::optional<pipeline::ZoneRecords> ClusterNode::next_records() {
  if (auto records = catch_up()) return records;
  return followed_records();
}

// A held zone's log after what the world has (a zone just taken, or an append in doubt).
std::optional<pipeline::ZoneRecords> ClusterNode::catch_up() {
  for (;;) {
    const std::optional<ZoneTable::CatchUp> c = table_.next_catch_up();
    if (!c) return std::nullopt;
    const std::optional<store::ZoneRow> row = read_db_.read(c->zone);
    if (!row || row->epoch != c->epoch) {  // taken by another node meanwhile
      table_.lost(c->zone, c->epoch);
      continue;
    }
    targets_[c->zone] = row->last_seq;
    pipeline::ZoneRecords out{
        .zone = c->zone, .epoch = c->epoch, .edits = {}, .through = c->applied};
    if (row->last_seq <= c->applied) return out;
    for (const store::ZoneRecord& r : read_db_.read_log(c->zone, c->applied, kRecordsPerRead)) {
      if (r.seq > row->last_seq) break;
      std::string why;
      std::optional<store::LoggedEdit> e = decode_zone_edit(r, &why);
      if (!e)
        throw store::StoreError(store_.name() + ": " + describe(c->zone) + " record " +
                                std::to_string(r.seq) + ": " + why);
      out.edits.push_back(std::move(*e));
      out.through = r.seq;
    }
    return out;
  }
}

// Records of a followed zone, as its owner committed them.
std::optional<pipeline::ZoneRecords> ClusterNode::followed_records() {
  std::optional<ZoneReplicas::Taken> taken = replicas_.take(
      kRecordsPerRead, [this](world::ZoneId z) { return table_.held(z); },
      [this](world::ZoneId z) { return table_.applied(z); });
  if (!taken) return std::nullopt;
  const world::ZoneId zone = taken->zone;
  const uint64_t applied = table_.applied(zone);
  if (taken->records.front().seq != applied + 1) {
    // Not the next record (this node's world moved otherwise): the log has the ones between.
    taken->records = read_db_.read_log(zone, applied, kRecordsPerRead);
    if (taken->records.empty()) return std::nullopt;
  }
  pipeline::ZoneRecords out{.zone = zone, .epoch = 0, .edits = {}, .through = applied};
  for (const store::ZoneRecord& r : taken->records) {
    std::string why;
    std::optional<store::LoggedEdit> e = decode_zone_edit(r, &why);
    if (!e) {
      replicas_.give_back(zone, std::move(taken->records));
      throw store::StoreError(store_.name() + ": " + describe(zone) + " record " +
                              std::to_string(r.seq) + ": " + why);
    }
    out.edits.push_back(std::move(*e));
    out.through = r.seq;
  }
  handed_ = std::move(taken->records);
  return out;
}

void ClusterNode::applied(const pipeline::ZoneRecords& records, uint64_t through) {
  if (records.epoch == 0) {  // a followed zone's
    table_.committed(records.zone, through);
    std::erase_if(handed_, [&](const store::ZoneRecord& r) { return r.seq <= through; });
    if (!handed_.empty()) replicas_.give_back(records.zone, std::move(handed_));
    handed_.clear();
    return;
  }
  const auto it = targets_.find(records.zone);
  const bool complete = it != targets_.end() && through >= it->second;
  if (complete) {
    // Its records continue from here; then edits in it are taken.
    publisher_.adopt(records.zone, through);
    targets_.erase(it);
  }
  table_.caught_up(records.zone, records.epoch, through, complete);
  if (complete && !table_.held(records.zone)) publisher_.forget(records.zone);
  if (complete && table_.writable(records.zone))
    spdlog::info("cluster: {} is writable here (its log applied through record {})",
                 describe(records.zone), through);
}

}  // namespace vox::cluster
