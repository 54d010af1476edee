// A cluster node's zones as its world sees them (docs/CLUSTER.md): for each zone it holds,
// the epoch and whether its world has caught up with the zone's log (only then are edits
// in it taken); for every zone its world has records of, the last one applied. The keeper
// reports takes and losses, the appender commits and appends in doubt, the pipeline
// catch-ups. Bounded by the zones a node was asked for (ZoneKeeper::Config::max_zones).
//
// Threads: any; one leaf lock, never held across I/O or a callback.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <vector>

#include "server/pipeline/edit_ids.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

class ZoneTable {
 public:
  // The keeper took `zone` at `epoch`: its world catches up before edits are taken.
  void taken(world::ZoneId zone, uint64_t epoch);
  // The zone is no longer held at `epoch` (a later epoch's take is left alone). When a
  // chunk of it was evicted meanwhile, it becomes fresh (see may_evict).
  void lost(world::ZoneId zone, uint64_t epoch);
  // A graceful hand-off's first step: no edit is taken in it any more (they go to its next
  // holder), while the appends already made land under its epoch; lost() follows.
  void leave(world::ZoneId zone, uint64_t epoch);
  bool leaving(world::ZoneId zone) const;
  // Edits in it are taken: its epoch; nullopt when it is not held or still catching up.
  std::optional<uint64_t> writable(world::ZoneId zone) const;
  // Its appends land: its epoch while held and caught up, being handed off or not.
  std::optional<uint64_t> appendable(world::ZoneId zone) const;
  bool held(world::ZoneId zone) const;

  // An append of these zones whose outcome is in doubt: they catch up again (whatever of
  // it landed is applied from the log; the pipeline undid it).
  void doubt(world::ZoneId zone);
  // Records through `last` of `zone` are durable and applied.
  void committed(world::ZoneId zone, uint64_t last);

  // A held zone whose world is behind (and not fresh): its epoch and the last record
  // applied. The first after `after` (in zone order, around): a zone whose log cannot be
  // read or applied now holds up no other.
  struct CatchUp {
    world::ZoneId zone;
    uint64_t epoch = 0, applied = 0;
  };
  std::optional<CatchUp> next_catch_up(std::optional<world::ZoneId> after = std::nullopt) const;
  bool catching_up() const;
  // The pipeline applied the zone's records through `through`; `complete`: the log has no
  // more (the zone becomes writable, if still held at `epoch`).
  void caught_up(world::ZoneId zone, uint64_t epoch, uint64_t through, bool complete);
  // The last record its world has (0 while fresh: it has to be installed afresh).
  uint64_t applied(world::ZoneId zone) const;

  // Evicting a zone's chunks (docs/CLUSTER.md, "Evicting a zone's chunks"). may_evict:
  // whether a saved changed chunk of the zone may leave memory now (only while the zone
  // is held and caught up: it is read back from the zone's checkpoint, which nobody else
  // moves meanwhile); true notes that one did. fresh: the zone was lost since one did, so
  // the chunks read back might be ahead of what the world has: its chunks go back to the
  // generated terrain, its checkpoint and log are applied from there. reset: the pipeline
  // did so, applying the zone's records through `through`.
  bool may_evict(world::ZoneId zone);
  struct Position {
    uint64_t applied = 0;  // 0 when fresh
    bool fresh = false;
  };
  Position position(world::ZoneId zone) const;  // applied() and fresh, read at once
  // A fresh zone (held or not: a held one catches up once its world forgot it).
  std::optional<world::ZoneId> next_fresh() const;
  void reset(world::ZoneId zone, uint64_t through);
  // The zones edits are taken in now.
  std::vector<world::ZoneId> writable_zones() const;

  // A checkpoint starts: the zones whose chunks it writes (held, their logs applied,
  // being handed off or not), each with its epoch and last record applied, and whether it
  // writes every changed chunk of the zone (the first since the zone was taken or caught
  // up again: chunks it changed before were not this holder's to write).
  struct CheckpointZone {
    world::ZoneId zone;
    uint64_t epoch = 0, applied = 0;
    bool whole = false;
  };
  std::vector<CheckpointZone> start_checkpoint();

  // Edit ids (docs/CLUSTER.md, "Edits across a border"): whether the zone's world has the
  // edit `id`, among the last kRememberedEdits noted for the zone (the log is asked for
  // older ones). Noted when the pipeline applies an edit or its records; forgotten when
  // the append that held it failed (the pipeline undid it).
  static constexpr size_t kRememberedEdits = 8192;
  bool has_edit(world::ZoneId zone, uint64_t id) const;
  void note_edit(world::ZoneId zone, uint64_t id);
  void forget_edit(world::ZoneId zone, uint64_t id);

  // A zone neither held nor followed any more is forgotten whole, so that a node's memory
  // stays bounded: its edit ids (a later follow or take notes them again from its log),
  // and its world, which becomes fresh (its chunks leave memory; installed afresh when next
  // followed or taken). known_unheld: the zones not held whose world or edit ids are
  // remembered. forget: nothing when the zone is held.
  std::vector<world::ZoneId> known_unheld() const;
  void forget(world::ZoneId zone);

 private:
  struct Zone {
    std::optional<uint64_t> epoch;  // held at
    bool behind = false;            // held, the world not caught up yet
    bool leaving = false;           // held, being handed off
    bool swept = false;             // a checkpoint since it caught up wrote it whole
    uint64_t applied = 0;           // the last record the world has
    bool evicted = false;           // held, and a changed chunk of it was evicted
    bool fresh = false;             // lost after evicted, or forgotten: its world forgets it
    pipeline::EditIds edits{kRememberedEdits};
  };
  mutable std::mutex mutex_;
  std::map<world::ZoneId, Zone> zones_;
};

}  // namespace vox::cluster
