// A voxeld node of a cluster world (docs/CLUSTER.md): its links to the cluster's NATS and
// PostgreSQL, the keeper of its zones, the world store its pipeline appends to (each
// edit to its zone's log, fenced, then published) and what the pipeline asks about zones
// (pipeline::ZoneAuthority): an edit is taken only in zones this node holds and whose
// log its world has caught up with; a zone just taken, or whose append was in doubt, has
// its log applied first. An edit in a zone it does not hold is refused, and the node asks
// for the zone (it takes it when it ranks first among the live nodes). The zones its
// players view and it does not hold are followed (ZoneReplicas): their records are applied
// to its world as they are committed elsewhere, and it meshes them itself.
//
// Threads: construct, start and stop on one thread (the daemon's); the ZoneAuthority
// members on the pipeline thread; store() is the pipeline's (its appender's thread). The
// keeper's callbacks run on its thread and only update the zone table.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>

#include "server/cluster/cluster_config.hpp"
#include "server/cluster/edit_forwarder.hpp"
#include "server/cluster/nats_link.hpp"
#include "server/cluster/part_completer.hpp"
#include "server/cluster/zone_keeper.hpp"
#include "server/cluster/zone_log_store.hpp"
#include "server/cluster/zone_publisher.hpp"
#include "server/cluster/zone_record_source.hpp"
#include "server/cluster/zone_replicas.hpp"
#include "server/cluster/zone_table.hpp"
#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/zone_authority.hpp"
#include "server/store/zone_leases.hpp"

namespace vox::cluster {

class ClusterNode : public pipeline::ZoneAuthority {
 public:
  // Connects to NATS and PostgreSQL and checks the world's settings (seed, zone size)
  // against the database's: throws ClusterError or store::StoreError with one line.
  ClusterNode(ClusterConfig config, uint64_t seed);
  ~ClusterNode() override;  // stop(false)
  ClusterNode(const ClusterNode&) = delete;
  ClusterNode& operator=(const ClusterNode&) = delete;

  store::WorldStore& store() { return store_; }
  // How edits forwarded by other nodes reach this node's pipeline (WorldPipeline::submit
  // with `forwarded`); set before start.
  // (the task's forwarded, edit_id and part set; `done` answers the other node).
  using Submit = std::function<void(pipeline::EditTask task)>;
  void set_submit(Submit submit) { submit_ = std::move(submit); }
  // The version of this node's published mesh of a chunk, 0 for none (any thread; set
  // before start): a forwarded edit's changed_chunks are the chunks around it whose mesh
  // here changed between its forwarding and its answer.
  using MeshVersionOf = std::function<uint64_t(world::ChunkCoord)>;
  void set_mesh_version(MeshVersionOf of) { mesh_version_ = std::move(of); }
  // Starts taking zones and answering edits forwarded to them (after the pipeline exists:
  // it set its wake-up). `address`: where players reach this node (the live nodes' list).
  void start(const std::string& address);
  // Stops the keeper: `release` hands every zone off at once (after the pipeline stopped:
  // its appends have landed), else the leases run out (a crash's way). Idempotent.
  void stop(bool release);

  const std::string& node() const { return config_.node; }
  // Any thread: why this node should not take players now (its health check's 503:
  // docs/CLUSTER.md, "Clients"), or nullopt.
  std::optional<std::string> unhealthy() const;
  size_t zones_held() const { return keeper_ ? keeper_->held_count() : 0; }
  size_t zones_followed() const { return replicas_.followed(); }
  uint64_t fenced() const { return append_db_.fenced(); }  // appends the fence refused
  // What /metrics shows of the node (any thread).
  struct Figures {
    size_t zones_held = 0, zones_followed = 0;
    uint64_t appends_fenced = 0, edits_forwarded = 0, forwards_unheld = 0, forwards_timed_out = 0;
    uint64_t edits_split = 0, parts_completed = 0;
    uint64_t checkpoints_written = 0, checkpoints_fenced = 0, checkpoints_installed = 0;
  };
  Figures figures() const;

  // pipeline::ZoneAuthority (the pipeline thread).
  void set_wake(std::function<void()> wake) override { wake_ = std::move(wake); }
  int zone_chunks() const override { return config_.zone_chunks; }
  Verdict admit(pipeline::EditTask& task, const world::VoxelBox& box,
                std::vector<world::VoxelBox>& keep, std::string& why) override;
  void accepted(const pipeline::EditTask& task) override;
  void undone(const pipeline::EditTask& task) override;
  pipeline::CheckpointScope checkpoint_scope(uint64_t seq) override;
  void viewing(uint64_t owner, world::ChunkCoord center, int radius) override;
  bool may_evict(world::ChunkCoord c) override {
    return table_.may_evict(world::zone_of(c, config_.zone_chunks));
  }
  bool records_waiting() override { return records_.waiting(); }
  bool regions_changed() override { return store_.regions_stale(); }
  std::optional<store::RegionTable> take_regions() override { return store_.take_regions(); }
  std::optional<pipeline::ZoneRecords> next_records() override { return records_.next(); }
  void applied(const pipeline::ZoneRecords& records, uint64_t through) override;

 private:
  void taken(world::ZoneId zone, uint64_t epoch);  // the keeper's thread
  void lost(world::ZoneId zone, uint64_t epoch);   // likewise
  void round(store::ZoneLeases& db);               // likewise, after each round
  void serve(const NatsMessage& m);                // a NATS thread: a forwarded edit
  void regions_heard(uint64_t version);            // any thread
  // A forwarded edit's answer, relayed to the player once this node's world shows it (or
  // a while later: the zone may not be followed here).
  using Versions = std::vector<std::pair<world::ChunkCoord, uint64_t>>;
  void relay(EditReply reply, Versions before,
             std::function<void(const pipeline::EditResult&)> done);
  Versions versions_around(const world::VoxelBox& box) const;
  Verdict admit_part(pipeline::EditTask& task, std::vector<world::VoxelBox>& keep,
                     std::string& why);
  // An edit across zones not all writable here: one part per zone, each to its holder.
  void split(pipeline::EditTask& task, const std::vector<world::ZoneId>& zones,
             const world::VoxelBox& box);
  uint64_t new_edit_id();
  std::vector<world::ZoneId> zones_written(const pipeline::EditTask& task) const;
  bool mark_viewed(world::ChunkCoord center, int radius);  // any thread
  void release_relays(bool all);                           // any thread
  void ask_to_take(world::ZoneId zone);                    // any thread

  const ClusterConfig config_;
  NatsLink nats_;
  store::ZoneLeases append_db_;      // the appender thread's connection
  store::ZoneLeases read_db_;        // the pipeline thread's: zone logs and rows
  store::ZoneLeases checkpoint_db_;  // the checkpoint writer's (through store_)
  ZonePublisher publisher_;
  ZoneTable table_;
  ZoneLogStore store_;
  std::function<void()> wake_;  // set before start()
  ZoneReplicas replicas_;
  ZoneRecordSource records_;    // what the world applies; the pipeline thread
  Submit submit_;               // set before start()
  MeshVersionOf mesh_version_;  // likewise
  std::unique_ptr<EditForwarder> forwarder_;
  std::unique_ptr<PartCompleter> completer_;
  const uint64_t edit_id_base_;  // random: ids of edits this node splits
  std::atomic<uint64_t> edits_split_{0};
  std::atomic<uint64_t> edit_counter_{0};
  uint64_t take_subscription_ = 0, regions_subscription_ = 0;
  std::map<world::ZoneId, uint64_t> serving_;  // the keeper's thread: edit subscriptions
  struct Relay {
    std::vector<std::pair<world::ZoneId, uint64_t>> zones;
    std::chrono::steady_clock::time_point deadline;
    pipeline::EditResult result;
    std::function<void(const pipeline::EditResult&)> done;
    Versions before;  // the meshes around the edit when it was forwarded
  };
  // Guards relays_ (bounded by the forwarder's pending bound); taken before the zone table's
  // lock, never held across a callback.
  std::mutex relay_mutex_;
  std::vector<Relay> relays_;
  // Each session's current view (one per session: bounded by the sessions), marked viewed
  // again every round. A leaf lock.
  std::mutex views_mutex_;
  std::unordered_map<uint64_t, std::pair<world::ChunkCoord, int>> views_;
  std::unique_ptr<ZoneKeeper> keeper_;
  std::atomic<bool> started_{false};  // keeper_ is set (unhealthy() reads it)
};

}  // namespace vox::cluster
