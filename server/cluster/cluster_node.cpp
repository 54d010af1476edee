#include "server/cluster/cluster_node.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <climits>
#include <random>

#include "server/cluster/edit_wire.hpp"
#include "server/cluster/zone_wire.hpp"
#include "server/store/postgres_store.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::cluster {

namespace {

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

}  // namespace

ClusterNode::ClusterNode(ClusterConfig config, uint64_t seed)
    : config_(std::move(config)),
      nats_(config_.nats),
      append_db_(config_.database, config_.node, config_.lease),
      read_db_(config_.database, config_.node, config_.lease),
      checkpoint_db_(config_.database, config_.node, config_.lease),
      publisher_(nats_, append_db_, config_.world),
      store_(table_, publisher_, checkpoint_db_, read_db_, config_.zone_chunks, seed,
             "cluster world " + config_.world + " (" + store::redact_uri(config_.database) + ")"),
      replicas_(nats_,
                {.world = config_.world,
                 .uri = config_.database,
                 .node = config_.node,
                 .max_zones = static_cast<size_t>(config_.max_followed_zones),
                 .idle = config_.follow_idle},
                [this] {
                  if (wake_) wake_();
                }),
      records_(table_, replicas_, publisher_, read_db_, store_.name()),
      edit_id_base_((uint64_t{std::random_device{}()} << 32) ^ std::random_device{}()) {
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

namespace {

std::string take_subject(const std::string& world) { return "vox." + world + ".take"; }

}  // namespace

void ClusterNode::start(const std::string& address) {
  // A holder silent for a lease has likely lost its zones too: the edit is refused and the
  // zone asked for, rather than the player kept waiting.
  forwarder_ = std::make_unique<EditForwarder>(
      nats_,
      EditForwarder::Config{.world = config_.world,
                            .timeout = std::max(config_.lease, std::chrono::milliseconds(1000))},
      [this](world::ZoneId zone) { ask_to_take(zone); });
  keeper_ = std::make_unique<ZoneKeeper>(
      ZoneKeeper::Config{.uri = config_.database,
                         .node = config_.node,
                         .address = address,
                         .lease = config_.lease},
      ZoneKeeper::Events{
          .taken = [this](world::ZoneId z, uint64_t epoch) { taken(z, epoch); },
          .lost = [this](world::ZoneId z, uint64_t epoch) { lost(z, epoch); },
          .round = [this](store::ZoneLeases& db) { round(db); },
          // The node now ranking first takes it at once, not at the next edit.
          .handed_off = [this](world::ZoneId z) { ask_to_take(z); },
          .leaving = [this](world::ZoneId z, uint64_t epoch) { table_.leave(z, epoch); }});
  // Parts of edits across zones left undone in the zones held here (their requests were
  // lost with a node, or refused) are completed once well past a forward's timeout.
  completer_ = std::make_unique<PartCompleter>(
      PartCompleter::Config{.uri = config_.database,
                            .node = config_.node,
                            .lease = config_.lease,
                            .age = 2 * std::max(config_.lease, std::chrono::milliseconds(1000)) +
                                   std::chrono::milliseconds(1000)},
      [this] { return table_.writable_zones(); },
      [this](pipeline::EditTask task) { submit_(std::move(task)); });
  take_subscription_ = nats_.subscribe(take_subject(config_.world), [this](const NatsMessage& m) {
    if (m.data.size() != 8) return;
    uint64_t key = 0;
    for (int i = 0; i < 8; ++i) key |= uint64_t{m.data[i]} << (8 * i);
    keeper_->want(world::ZoneId::from_key(key));
  });
  // Another node changed the protected regions: the pipeline takes them before its next
  // batch (an append clipped by the old table would be refused).
  regions_subscription_ =
      nats_.subscribe(regions_subject(config_.world), [this](const NatsMessage& m) {
        if (const std::optional<uint64_t> version = decode_regions_version(m.data))
          regions_heard(*version);
      });
  started_.store(true, std::memory_order_release);
  spdlog::info("cluster: node {} of world {} (zones of {} chunks, lease {} ms), NATS {}",
               config_.node, config_.world, config_.zone_chunks, config_.lease.count(),
               nats_.server());
}

std::optional<std::string> ClusterNode::unhealthy() const {
  if (!started_.load(std::memory_order_acquire)) return "node " + config_.node + " is starting";
  if (!nats_.connected()) return "node " + config_.node + " has lost NATS";
  return keeper_->unhealthy();
}

// Whoever ranks first among the live nodes takes the zone (every node hears this, this
// one too; the holder, if it lives, keeps it).
void ClusterNode::ask_to_take(world::ZoneId zone) {
  const uint64_t key = zone.key();
  std::vector<uint8_t> bytes(8);
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(key >> (8 * i));
  try {
    nats_.publish(take_subject(config_.world), bytes);
  } catch (const ClusterError&) {  // the next edit asks again
  }
}

ClusterNode::Figures ClusterNode::figures() const {
  Figures f;
  f.zones_held = zones_held();
  f.zones_followed = zones_followed();
  f.appends_fenced = fenced();
  if (const EditForwarder* fw = forwarder_.get()) {
    f.edits_forwarded = fw->forwarded();
    f.forwards_unheld = fw->unheld();
    f.forwards_timed_out = fw->timed_out();
  }
  f.edits_split = edits_split_.load(std::memory_order_relaxed);
  if (const PartCompleter* pc = completer_.get()) f.parts_completed = pc->completed();
  f.checkpoints_written = store_.checkpoints_written();
  f.checkpoints_fenced = checkpoint_db_.fenced();
  f.checkpoints_installed = records_.installed();
  return f;
}

void ClusterNode::stop(bool release) {
  if (completer_) completer_->stop();  // submits nothing more
  for (uint64_t* id : {&take_subscription_, &regions_subscription_}) {
    if (*id != 0) nats_.unsubscribe(*id);
    *id = 0;
  }
  if (keeper_) keeper_->stop(release);  // its thread has ended: serving_ is ours now
  for (const auto& [zone, id] : serving_) nats_.unsubscribe(id);
  serving_.clear();
  forwarder_.reset();  // refuses what still waits for an answer
  release_relays(true);
  replicas_.stop();  // no record, and no wake-up of the pipeline, comes after this
}

void ClusterNode::taken(world::ZoneId zone, uint64_t epoch) {
  table_.taken(zone, epoch);  // the keeper logged it
  if (wake_) wake_();
  if (serving_.count(zone)) return;
  try {  // edits forwarded to it: answered (refused while its log is applied)
    serving_[zone] = nats_.subscribe(zone_subject(config_.world, zone, "edit"),
                                     [this](const NatsMessage& m) { serve(m); });
  } catch (const ClusterError& e) {
    spdlog::warn("cluster: cannot answer edits for {}: {}", describe(zone), e.what());
  }
}

void ClusterNode::lost(world::ZoneId zone, uint64_t epoch) {
  table_.lost(zone, epoch);       // likewise
  if (table_.held(zone)) return;  // taken again since
  publisher_.forget(zone);
  if (const auto it = serving_.find(zone); it != serving_.end()) {
    nats_.unsubscribe(it->second);  // waits for a handler in progress (it only submits)
    serving_.erase(it);
  }
}

void ClusterNode::serve(const NatsMessage& m) {
  if (m.reply.empty() || !submit_) return;
  std::string why;
  std::optional<EditRequest> request = decode_edit_request(m.data, &why);
  if (!request) {
    EditReply refused;
    refused.reason = world::RefusalReason::kStorageUnavailable;
    refused.message = "the node holding the zone could not read the forwarded edit: " + why;
    try {
      nats_.publish(m.reply, encode_edit_reply(refused));
    } catch (const ClusterError&) {  // the gateway times out
    }
    return;
  }
  // Its zones: a part's own, else all it touches.
  const std::vector<world::ZoneId> zones =
      request->part ? std::vector<world::ZoneId>{*request->part}
                    : world::zones_of(world::touched_box(request->edit), config_.zone_chunks);
  pipeline::EditTask task;
  task.edit = std::move(request->edit);
  task.author = std::move(request->author);
  task.bypass_regions = request->bypass_regions;
  task.forwarded = true;
  task.edit_id = request->edit_id;
  task.part = request->part;
  task.done = [this, reply_to = m.reply, id = request->id, zones](const pipeline::EditResult& r) {
    EditReply out;
    out.id = id;
    out.reason = r.accepted ? world::RefusalReason::kNone : r.reason;
    out.message = r.message;
    // Durable: each zone's log holds it, at or before its last record now.
    if (r.accepted) {
      for (const world::ZoneId zone : zones) out.zones.emplace_back(zone, table_.applied(zone));
    }
    out.changed_chunks = r.changed_chunks;
    out.clipped_by = r.clipped_by;
    out.already_applied = r.already_applied;
    out.zone_moving = r.zone_moving;
    try {
      nats_.publish(reply_to, encode_edit_reply(out));
    } catch (const ClusterError&) {  // the gateway times out
    }
  };
  submit_(std::move(task));
}

// The meshes this node has of the chunks whose meshes read an edit's samples (its box and
// one voxel around).
ClusterNode::Versions ClusterNode::versions_around(const world::VoxelBox& box) const {
  Versions out;
  if (!mesh_version_) return out;
  world::VoxelBox around = box;
  for (int i = 0; i < 3; ++i) {
    around.lo[i] = around.lo[i] > INT32_MIN ? around.lo[i] - 1 : around.lo[i];
    around.hi[i] = around.hi[i] < INT32_MAX ? around.hi[i] + 1 : around.hi[i];
  }
  for (const world::ChunkCoord& c : world::chunks_overlapping(around))
    out.emplace_back(c, mesh_version_(c));
  return out;
}

void ClusterNode::relay(EditReply reply, Versions before,
                        std::function<void(const pipeline::EditResult&)> done) {
  pipeline::EditResult result;
  result.accepted = reply.reason == world::RefusalReason::kNone;
  result.reason = reply.reason;
  result.message = std::move(reply.message);
  result.clipped_by = std::move(reply.clipped_by);
  result.already_applied = result.accepted && reply.already_applied;
  // Its meshes before its result, as on a single node: wait for the zones this node
  // follows to show it (at most a moment: a follower may be slow to start).
  std::erase_if(reply.zones, [this](const auto& z) { return !replicas_.following(z.first); });
  {
    std::lock_guard lock(relay_mutex_);
    relays_.push_back(Relay{std::move(reply.zones),
                            std::chrono::steady_clock::now() + std::chrono::seconds(2),
                            std::move(result), std::move(done), std::move(before)});
  }
  release_relays(false);
}

void ClusterNode::release_relays(bool all) {
  const auto now = std::chrono::steady_clock::now();
  std::vector<Relay> ready;
  {
    std::lock_guard lock(relay_mutex_);
    for (auto it = relays_.begin(); it != relays_.end();) {
      bool shown = true;
      for (const auto& [zone, seq] : it->zones) shown = shown && table_.applied(zone) >= seq;
      if (all || shown || now >= it->deadline) {
        ready.push_back(std::move(*it));
        it = relays_.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (Relay& r : ready) {
    if (r.result.accepted && !r.result.already_applied) {
      // Its changed chunks as this node shows them: the meshes around it that changed.
      for (const auto& [c, version] : r.before) {
        if (mesh_version_ && mesh_version_(c) != version) r.result.changed_chunks.push_back(c);
      }
    }
    if (r.done) r.done(r.result);
  }
}

void ClusterNode::regions_heard(uint64_t version) {
  store_.heard_regions(version);
  if (store_.regions_stale() && wake_) wake_();
}

void ClusterNode::round(store::ZoneLeases& db) {
  publisher_.heartbeat();
  try {  // a regions message lost on the way (NATS down) is made up for here
    regions_heard(db.regions_version());
  } catch (const store::StoreError&) {  // the keeper's round says so
  }
  release_relays(false);
  // Views still there are viewed now (a player standing still sends no new view): their
  // zones stay followed, and are never forgotten under their eyes.
  std::vector<std::pair<world::ChunkCoord, int>> views;
  {
    std::lock_guard lock(views_mutex_);
    views.reserve(views_.size());
    for (const auto& [owner, view] : views_) views.push_back(view);
  }
  for (const auto& [center, radius] : views) mark_viewed(center, radius);
  replicas_.reconcile([this](world::ZoneId z) { return table_.held(z); },
                      [this](world::ZoneId z) { return table_.applied(z); });
  // Zones neither held nor followed nor viewed lately (one waiting for a follower keeps
  // what it has meanwhile) are forgotten: the memory stays bounded.
  for (const world::ZoneId zone : table_.known_unheld()) {
    if (!replicas_.following(zone) && !replicas_.viewed_lately(zone)) table_.forget(zone);
  }
  // Zones forgotten, or lost after an eviction: the pipeline forgets their chunks now.
  if (table_.next_fresh() && wake_) wake_();
}

void ClusterNode::viewing(uint64_t owner, world::ChunkCoord center, int radius) {
  {
    std::lock_guard lock(views_mutex_);
    if (radius < 0) {
      views_.erase(owner);
      return;
    }
    views_[owner] = {center, radius};
  }
  // A zone newly viewed is followed from the keeper's next round: started now, not in up
  // to a third of a lease (its view showed the generated terrain meanwhile).
  if (mark_viewed(center, radius) && keeper_) keeper_->poke();
}

// Whether a zone of the view was not followed and now may be.
bool ClusterNode::mark_viewed(world::ChunkCoord center, int radius) {
  // Plus a chunk around: a mesh at the view's edge reads a voxel of its neighbours.
  const int64_t r = std::clamp(radius, 0, 1 << 16) + 1;
  const auto voxel = [](int64_t chunk) {
    return static_cast<int32_t>(
        std::clamp<int64_t>(chunk * world::kChunkSize, INT32_MIN + 64, INT32_MAX - 64));
  };
  const world::VoxelBox box{{voxel(center.x - r), 0, voxel(center.z - r)},
                            {voxel(center.x + r), 0, voxel(center.z + r)}};
  // Views are at most a few dozen chunks across; the replicas bound what they remember.
  bool fresh = false;
  for (const world::ZoneId zone : world::zones_of(box, config_.zone_chunks))
    fresh = (replicas_.viewing(zone) && !table_.held(zone)) || fresh;
  return fresh;
}

pipeline::ZoneAuthority::Verdict ClusterNode::admit(pipeline::EditTask& task,
                                                    const world::VoxelBox& box,
                                                    std::vector<world::VoxelBox>& keep,
                                                    std::string& why) {
  if (task.part) return admit_part(task, keep, why);
  // The zones it writes (a smooth reads only within each sample's zone: the same).
  const std::vector<world::ZoneId> zones =
      world::zones_of(world::touched_box(task.edit), config_.zone_chunks);
  bool all_writable = true;
  for (const world::ZoneId zone : zones) {
    if (table_.writable(zone)) continue;
    all_writable = false;
    if (table_.held(zone) && !table_.leaving(zone)) {
      why = describe(zone) + " is being loaded on this node; retry shortly";
      return Verdict::kNotHere;
    }
  }
  if (all_writable) {
    for (const world::ZoneId zone : zones) {
      if (table_.has_edit(zone, task.edit_id)) {
        why = "this edit was applied already";
        return Verdict::kAlreadyApplied;
      }
    }
    return Verdict::kWritable;
  }
  if (task.forwarded || !forwarder_) {
    why = describe(zones.front()) + " is not held by this node (any more); retry shortly";
    return Verdict::kNotHere;
  }
  if (zones.size() > 1) {
    split(task, zones, box);
    return Verdict::kForwarded;
  }
  forwarder_->forward(zones.front(),
                      EditRequest{.id = 0,
                                  .bypass_regions = task.bypass_regions,
                                  .edit_id = task.edit_id != 0 ? task.edit_id : new_edit_id(),
                                  .part = std::nullopt,
                                  .author = task.author,
                                  .edit = task.edit},
                      [this, before = versions_around(box), done = std::move(task.done)](
                          const EditReply& r) { relay(r, before, done); });
  task.done = nullptr;
  return Verdict::kForwarded;
}

// One zone's part of an edit across zones held by different nodes: a gateway sent it, or
// this node completes it (PartCompleter). Only the zone's own samples are written.
pipeline::ZoneAuthority::Verdict ClusterNode::admit_part(pipeline::EditTask& task,
                                                         std::vector<world::VoxelBox>& keep,
                                                         std::string& why) {
  const world::ZoneId zone = *task.part;
  const world::VoxelBox touched = world::touched_box(task.edit);
  const std::vector<world::ZoneId> zones = world::zones_of(touched, config_.zone_chunks);
  if (task.edit_id == 0 || std::find(zones.begin(), zones.end(), zone) == zones.end()) {
    why = "a part of an edit that is not one (no edit id, or a zone it misses)";
    return Verdict::kRefused;
  }
  if (!table_.writable(zone)) {
    why = describe(zone) + (table_.held(zone) && !table_.leaving(zone)
                                ? " is being loaded on this node; retry shortly"
                                : " is not held by this node (any more); retry shortly");
    return Verdict::kNotHere;
  }
  if (table_.has_edit(zone, task.edit_id)) {
    why = "this part of the edit was applied already";
    return Verdict::kAlreadyApplied;
  }
  keep = world::outside_zone(touched, zone, config_.zone_chunks);
  return Verdict::kWritable;
}

// The zones whose samples an applied edit wrote: a part's own, else all it touches.
std::vector<world::ZoneId> ClusterNode::zones_written(const pipeline::EditTask& task) const {
  if (task.part) return {*task.part};
  return world::zones_of(world::touched_box(task.edit), config_.zone_chunks);
}

void ClusterNode::accepted(const pipeline::EditTask& task) {
  if (task.edit_id == 0) return;
  for (const world::ZoneId zone : zones_written(task)) table_.note_edit(zone, task.edit_id);
}

void ClusterNode::undone(const pipeline::EditTask& task) {
  if (task.edit_id == 0) return;
  for (const world::ZoneId zone : zones_written(task)) table_.forget_edit(zone, task.edit_id);
}

uint64_t ClusterNode::new_edit_id() {
  // splitmix64 of a random base plus a counter: distinct here, and across nodes but for
  // a chance of one in 2^64 per pair.
  uint64_t z = edit_id_base_ +
               0x9e3779b97f4a7c15ULL * (edit_counter_.fetch_add(1, std::memory_order_relaxed) + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return z == 0 ? 1 : z;
}

namespace {

// The answers of an edit's parts, joined into the player's: accepted once any part is
// durable (that part's transaction left the others pending: they are certain to follow).
struct PartsJoin {
  std::mutex mutex;  // leaf
  size_t left = 0;
  bool accepted = false;
  bool all_applied_before = true;    // every accepted part a resend's
  EditReply reply;                   // the accepted parts' zones and regions
  std::optional<EditReply> refusal;  // the first refusal (one whose outcome is unknown first)
  size_t refused = 0;
  std::function<void(EditReply)> finish;  // the player's answer, once
};

}  // namespace

void ClusterNode::split(pipeline::EditTask& task, const std::vector<world::ZoneId>& zones,
                        const world::VoxelBox& box) {
  edits_split_.fetch_add(1, std::memory_order_relaxed);
  const uint64_t id = task.edit_id != 0 ? task.edit_id : new_edit_id();
  auto join = std::make_shared<PartsJoin>();
  join->left = zones.size();
  join->finish = [this, before = versions_around(box), done = std::move(task.done)](EditReply r) {
    relay(std::move(r), before, done);
  };
  task.done = nullptr;
  for (const world::ZoneId zone : zones) {
    forwarder_->forward(
        zone,
        EditRequest{.id = 0,
                    .bypass_regions = task.bypass_regions,
                    .edit_id = id,
                    .part = zone,
                    .author = task.author,
                    .edit = task.edit},
        [join, id](const EditReply& r) {
          std::unique_lock lock(join->mutex);
          if (r.reason == world::RefusalReason::kNone) {
            join->accepted = true;
            join->all_applied_before = join->all_applied_before && r.already_applied;
            join->reply.zones.insert(join->reply.zones.end(), r.zones.begin(), r.zones.end());
            join->reply.clipped_by.insert(join->reply.clipped_by.end(), r.clipped_by.begin(),
                                          r.clipped_by.end());
          } else {
            // A part whose outcome is unknown says so: the edit may have been applied.
            if (!join->refusal || (r.maybe_applied && !join->refusal->maybe_applied))
              join->refusal = r;
            ++join->refused;
          }
          if (--join->left > 0) return;
          EditReply out = join->accepted ? std::move(join->reply) : std::move(*join->refusal);
          out.already_applied = join->accepted && join->all_applied_before;
          if (join->accepted && join->refused > 0) {
            spdlog::debug(
                "cluster: edit {} accepted; {} of its parts follow when their zones' "
                "holders can take them",
                id, join->refused);
          }
          std::function<void(EditReply)> finish = std::move(join->finish);
          lock.unlock();
          finish(std::move(out));
        });
  }
}

pipeline::CheckpointScope ClusterNode::checkpoint_scope(uint64_t seq) {
  std::vector<ZoneTable::CheckpointZone> zones = table_.start_checkpoint();
  pipeline::CheckpointScope scope{.zone_chunks = config_.zone_chunks, .zones = {}, .whole = {}};
  for (const ZoneTable::CheckpointZone& z : zones) {
    scope.zones.push_back(z.zone);
    if (z.whole) scope.whole.push_back(z.zone);
  }
  store_.checkpoint_started(seq, std::move(zones));
  return scope;
}

void ClusterNode::applied(const pipeline::ZoneRecords& records, uint64_t through) {
  records_.applied(records, through);
  if (records.epoch == 0) release_relays(false);  // a followed zone's: its answers may go
}

}  // namespace vox::cluster
