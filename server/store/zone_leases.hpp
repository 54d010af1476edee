// Who owns each zone of a cluster world (server/world/zone.hpp), and the zones' logs, in
// PostgreSQL: liveness by leases whose expiry the database's clock judges, safety by
// fencing (Kleppmann, "How to do distributed locking").
//
// - A zone row holds its epoch, owner, lease end and last sequence number. Taking a zone
//   (never owned, released, or its lease past by the database's now()) bumps its epoch;
//   renewing keeps it. The owner renews about every lease / 3.
// - Every durable write of a zone checks, in its own transaction and under the zone row's
//   lock, that the writer's epoch is still the zone's: an owner paused past its lease
//   (GC, VM stall, SIGSTOP) whose zone was taken meanwhile can never write after its
//   successor, whatever its own clock says. Such a write throws FencedError and is
//   counted.
// - A zone's log numbers its records 1, 2, … without a gap: an append must continue the
//   zone's last sequence number (else StoreError), so sequences only increase, across
//   owners too.
// - Nodes announce themselves with a heartbeat row (alive until the database's now() +
//   lease); placement ranks the live ones (first_ranked).
//
// One ZoneLeases is one connection: one thread at a time; open one per thread. Failures
// (database gone, constraint broken) throw StoreError with a one-line message; the next
// call reconnects.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "server/store/world_store.hpp"
#include "server/world/zone.hpp"

namespace vox::store {

// A write refused because the zone's epoch moved on: another node took it.
struct FencedError : StoreError {
  FencedError(const std::string& what, world::ZoneId z) : StoreError(what), zone(z) {}
  world::ZoneId zone;  // the zone refused
};

// An append refused because the protected regions changed since the table its edits were
// clipped by (another node changed them; docs/CLUSTER.md, "Protected regions"): nothing
// was written and no zone is lost. `version`: the table's now.
struct RegionsChangedError : FencedError {
  RegionsChangedError(const std::string& what, uint64_t v) : FencedError(what, {}), version(v) {}
  uint64_t version;
};

// The protected regions an append's edits were clipped by: the cluster's table at
// `version`. With `write`, the append changes that table too (its version then + 1).
struct RegionsAt {
  uint64_t version = 0;
  const RegionWrite* write = nullptr;
};

// The cluster's protected regions and the version of the table.
struct ZoneRegions {
  RegionTable table;
  uint64_t version = 0;
};

struct ZoneRecord {
  uint64_t seq = 0;
  int64_t unix_ms = 0;
  std::vector<uint8_t> payload;  // an encoded edit (opaque here)
  uint64_t edit_id = 0;          // the edit's cluster-wide id (0: none)
};

// A logged edit as a zone record's payload (its seq and time are the record's), and back:
// nullopt, with `error` set, when the payload is not one.
std::vector<uint8_t> encode_zone_edit(const LoggedEdit& edit);
std::optional<LoggedEdit> decode_zone_edit(const ZoneRecord& record, std::string* error = nullptr);

// A part of an edit across zones that another zone's log must still get (docs/CLUSTER.md,
// "Edits across a border"): written with the part the writer logged, in its
// transaction, unless `zone`'s log has the edit already; removed when `zone`'s log gets
// it. Whoever holds `zone` completes what is left (roll forward).
struct ZonePending {
  world::ZoneId zone;
  uint64_t edit_id = 0;
  int64_t unix_ms = 0;
  std::vector<uint8_t> payload;  // the part as `zone`'s record will hold it
};

// One zone's part of an append (ZoneLeases::append).
struct ZoneAppend {
  world::ZoneId zone;
  uint64_t epoch = 0;
  std::span<const ZoneRecord> records;
  std::span<const ZonePending> pending;  // other zones' parts of these records' edits
};

struct ZoneRow {
  uint64_t epoch = 0;
  std::string owner;          // empty: released
  int64_t lease_left_ms = 0;  // by the database's clock; <= 0: expired
  uint64_t last_seq = 0;
  uint64_t checkpoint_seq = 0;  // the zone's checkpoint holds every record through this one
};

// A zone's checkpoint (docs/CLUSTER.md, "Zone checkpoints"): its chunks as of record `seq`
// of its log. Written by its holder: the chunks its records changed since the holder's
// last checkpoint (every chunk they ever changed, on its first after taking the zone).
// Read: every changed chunk of the zone, each in its latest version through the zone's
// checkpoint_seq; a chunk of the zone not among them was never changed by a record through
// it.
struct ZoneCheckpoint {
  world::ZoneId zone;
  uint64_t seq = 0;
  std::vector<ChunkRecord> chunks;  // seq: the record each chunk is at (<= `seq`)
  // Read only: the edit ids of the last records through `seq` (at most a ZoneTable's
  // memory of them; the newest last).
  std::vector<uint64_t> edit_ids;
};

// What every node of one cluster world must agree on (one world per database).
struct WorldSettings {
  std::string name;
  uint64_t seed = 0;
  int zone_chunks = 0;
  friend bool operator==(const WorldSettings&, const WorldSettings&) = default;
};

struct ZoneSeed {
  world::ZoneId zone;
  uint64_t epoch = 0;
  std::vector<ChunkRecord> chunks;
};

// Whether the database at `uri` holds a cluster world (its zones' tables); reads only.
bool is_cluster_world(const std::string& uri);

class ZoneLeases {
 public:
  // `node`: this node's id (non-empty, at most 200 bytes); `lease`: how long a lease and a
  // heartbeat last (at least 100 ms). Creates the tables when missing.
  ZoneLeases(std::string uri, std::string node, std::chrono::milliseconds lease);
  ~ZoneLeases();
  ZoneLeases(const ZoneLeases&) = delete;
  ZoneLeases& operator=(const ZoneLeases&) = delete;

  const std::string& node() const { return node_; }

  // Takes `zone` when it is free (never owned, released, or its lease past) or named as
  // this node's: a new epoch, the lease running from now; nullopt while another node's
  // lease runs. A zone named as this node's gets a new epoch too (a restarted process
  // with the same id fences its earlier run): to keep a zone, renew it.
  std::optional<uint64_t> acquire(world::ZoneId zone);
  // Renews this node's lease of `zone` at `epoch`: false once the zone is another's or
  // was released (a lease that ran out with nobody taking the zone is renewed: no
  // successor wrote).
  bool renew(world::ZoneId zone, uint64_t epoch);
  // Lets the zone go at once (a graceful hand-off); nothing when `epoch` is not current.
  void release(world::ZoneId zone, uint64_t epoch);

  // Appends `records` to the zone's log in one transaction, fenced by `epoch`; the first
  // record's seq must be the zone's last + 1 and the others follow without a gap.
  void append(world::ZoneId zone, uint64_t epoch, std::span<const ZoneRecord> records);
  // Several zones' appends in one transaction, each fenced by its epoch and continuing
  // its zone's sequence: all land or none (FencedError names the first zone refused).
  // With `regions`: refused (RegionsChangedError) unless the protected regions are still
  // at regions->version, and changed by regions->write in the same transaction (which
  // may hold no records). Returns the regions' version after it (0 without `regions`).
  uint64_t append(std::span<const ZoneAppend> appends, const RegionsAt* regions = nullptr);
  // The protected regions, in one snapshot; regions_version() alone (a cheap poll).
  ZoneRegions read_regions();
  uint64_t regions_version();
  // Migration: the regions of an empty cluster world become `table` (StoreError when it
  // has some already).
  void seed_regions(const RegionTable& table);
  // The parts the logs of `zones` still miss, written at least `age` ago by the database's
  // clock (younger ones are likely on their way), at most `max`; pending rows whose zone's
  // log has the edit by now are removed on the way.
  std::vector<ZonePending> read_pending(std::span<const world::ZoneId> zones,
                                        std::chrono::milliseconds age, size_t max = 256);
  // Removes a pending part (one that cannot be read: it would block the others).
  void drop_pending(world::ZoneId zone, uint64_t edit_id);
  // The zone's records after `after_seq`, in order (at most `max`).
  std::vector<ZoneRecord> read_log(world::ZoneId zone, uint64_t after_seq, size_t max = 10000);
  std::optional<ZoneRow> read(world::ZoneId zone);

  // Writes `checkpoint` of a zone held at `epoch`: its chunks in transactions of a few
  // dozen (no lock held; each a new version of its chunk, invisible to readers until the
  // zone's checkpoint_seq reaches it), then, in one short transaction fenced like an
  // append, the zone's checkpoint_seq (it only grows; at most the zone's last record) and
  // the removal of the versions these chunks replace. A write the fence refuses
  // (FencedError) leaves versions past the zone's checkpoint_seq: each is the chunk as a
  // prefix of the log left it, so a later checkpoint may keep it or replace it.
  void write_checkpoint(uint64_t epoch, const ZoneCheckpoint& checkpoint);
  // The zone's checkpoint, read in one snapshot (repeatable read): nullopt when it has none.
  // At most `max_edit_ids` edit ids.
  std::optional<ZoneCheckpoint> read_checkpoint(world::ZoneId zone, size_t max_edit_ids);
  // One chunk of the zone's checkpoint (its latest version through the zone's
  // checkpoint_seq): the chunk as the log through checkpoint_seq leaves it. A world that
  // applied the zone's records through `applied`, and has not changed the chunk since a
  // checkpoint that held it, may read it back so (docs/CLUSTER.md, "Evicting a zone's
  // chunks"). StoreError when the checkpoint is past `applied` (the chunk may have changed
  // since); nullopt when no checkpoint holds the chunk, or the zone has no row.
  std::optional<ChunkRecord> read_chunk(world::ZoneId zone, world::ChunkCoord chunk,
                                        uint64_t applied);

  // Every zone the database has a row of.
  std::vector<world::ZoneId> zones();
  // Migration (voxel-cli world migrate): each zone, with no record yet and held at its
  // epoch, gets its chunks as its first checkpoint, through record 1, which its log never
  // holds (its records start at 2; every reader installs the checkpoint first). All zones
  // in one transaction, fenced; StoreError when one has records or a checkpoint already.
  void seed_zones(std::span<const ZoneSeed> zones);

  // This node is alive for another lease: nullopt. A node id is one process's at a time
  // (each ZoneLeases is its own process's instance): while another's heartbeat for the
  // same id runs, refused, with that one's address (a restarted process waits for its
  // earlier run's heartbeat to run out; a second process given the same id stays out).
  // leave(): it leaves the live list at once (a graceful stop). live_nodes(): the nodes
  // alive now (by id).
  std::optional<std::string> heartbeat(const std::string& address);
  void leave();
  std::vector<std::string> live_nodes();

  // The world's settings: `mine` when the database has none yet (the first node made the
  // world), else those it has (the caller refuses to start when they differ).
  WorldSettings settle_world(const WorldSettings& mine);
  std::optional<WorldSettings> world_settings();  // reads only; nullopt: no world yet

  // Writes (appends, checkpoints) this object refused by the fence so far.
  uint64_t fenced() const { return fenced_.load(std::memory_order_relaxed); }  // any thread

 private:
  template <typename Fn>
  auto run(Fn&& fn);
  struct Connection;  // the libpqxx connection, opened on first use and after a loss

  std::string uri_, name_, node_;
  std::chrono::milliseconds lease_;
  int64_t instance_;  // this process's mark on the node's heartbeat row
  std::unique_ptr<Connection> conn_;
  std::atomic<uint64_t> fenced_{0};
};

}  // namespace vox::store
