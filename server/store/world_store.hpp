// The durable world: the log of accepted edits and checkpoints of modified chunks, behind
// one narrow interface with two backends (SQLite in a world directory, the default; and
// PostgreSQL, for a world that several processes share). Unmodified chunks are never
// stored: they regenerate from the seed.
//
// A WorldStore is one connection: not thread-safe; each thread that needs one opens its
// own (SQLite in WAL mode and PostgreSQL both let readers run beside the writer). Every
// failure (disk full, database gone, corrupt file) throws StoreError with a one-line
// message naming the store; a later call tries again (PostgreSQL reconnects).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/world/chunk.hpp"
#include "server/world/chunk_coord.hpp"
#include "server/world/edit.hpp"
#include "server/world/region.hpp"
#include "server/world/zone.hpp"

namespace vox::store {

struct StoreError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The schema this code writes; a store of a newer one is refused, never written.
inline constexpr int kSchemaVersion = 4;

struct LoggedEdit {
  uint64_t seq = 0;     // global sequence number, from 1, in the order the edits applied
  int64_t unix_ms = 0;  // when it was accepted
  std::string author;   // the player id (empty: an open server)
  world::Edit edit;
  // The samples it left as they were: protected regions its author could not change
  // (world/region.hpp). Replay leaves them too, so it is bit-identical whatever the
  // regions are by then.
  std::vector<world::VoxelBox> keep;
  // A cluster world (docs/CLUSTER.md): the id its gateway gave the edit (0: none), and,
  // for one part of an edit across zones held by different nodes, the zone it writes
  // (`keep` then holds the samples outside it).
  uint64_t edit_id = 0;
  std::optional<world::ZoneId> part;
  // A rollback record (docs/OPERATIONS.md), not an edit: the sequence numbers of the edits
  // (or records) it undoes, ascending; `edit` and `keep` are then unused.
  std::optional<std::vector<uint64_t>> undoes;
};

// A change of the stored protected regions, written in an append's transaction.
struct RegionWrite {
  bool whole = false;                 // the table becomes `upsert` (a repair), else:
  std::vector<world::Region> upsert;  // regions added
  std::vector<uint64_t> remove;       // ids removed (after the additions)
  uint64_t next_id = 1;               // the next id the server will give (ids are never reused)
};
struct RegionTable {
  std::vector<world::Region> regions;  // by id
  uint64_t next_id = 1;                // above every id ever given
};

// What a checkpoint deletes from the log: the edits through `through` (0: none), but from
// the first edit accepted at or after `accepted_before_ms` on, none (the history window:
// the log stays one contiguous tail). An edit stamped after `stamps_until_ms` (a clock
// that ran ahead) does not count as the first one kept.
struct LogTrim {
  LogTrim(uint64_t through_seq = 0,  // NOLINT: a plain seq trims it all, as before windows
          int64_t before_ms = std::numeric_limits<int64_t>::max(),
          int64_t until_ms = std::numeric_limits<int64_t>::max())
      : through(through_seq), accepted_before_ms(before_ms), stamps_until_ms(until_ms) {}
  uint64_t through = 0;
  int64_t accepted_before_ms = std::numeric_limits<int64_t>::max();
  int64_t stamps_until_ms = std::numeric_limits<int64_t>::max();
  bool windowed() const { return accepted_before_ms != std::numeric_limits<int64_t>::max(); }
};

struct ChunkRecord {
  world::ChunkCoord coord;
  uint64_t seq = 0;              // the samples include every edit up to this one
  std::vector<uint8_t> samples;  // encode_chunk()
};

struct WorldInfo {
  uint64_t seed = 0;
  uint64_t starts = 0;          // read-write opens so far (this one included)
  uint64_t last_seq = 0;        // the newest logged (or checkpointed) edit
  uint64_t checkpoint_seq = 0;  // the chunks include every edit up to this one
  uint64_t logged_edits = 0;    // rows in the log (those after trimming)
  uint64_t modified_chunks = 0;
  uint64_t size_bytes = 0;  // on disk, as the backend counts it
  // The history rollbacks reach (docs/OPERATIONS.md): the base chunks are the world as it
  // was after this edit, and the log holds every edit after it. nullopt: no base is kept
  // (the log was trimmed whole, or the world is from before rollbacks).
  std::optional<uint64_t> base_seq;
};

// How long opening a world as its writer waits for another writer's lock before refusing:
// a writer that has just stopped may hold it a moment longer (PostgreSQL drops a session's
// lock only once its backend has seen the connection close).
inline constexpr std::chrono::milliseconds kWriterLockWait{3000};

struct OpenOptions {
  // An existing world must have this seed (else StoreError naming both); nullopt: open it
  // whatever its seed. A new world records `seed`, or `new_world_seed` when it is unset.
  std::optional<uint64_t> seed;
  uint64_t new_world_seed = 1;
  bool read_only = false;  // tools: no write, works beside a running voxeld
  // The writer's first connection: counts this open in WorldInfo::starts, takes the
  // world's one-writer lock (refused, naming it, while another process holds it), deletes
  // an unfinished checkpoint's rows and (SQLite) checks the whole file first (PRAGMA
  // quick_check: it reads every page). False: a second connection of the same process.
  bool record_start = true;
};

class WorldStore {
 public:
  virtual ~WorldStore() = default;
  // "SQLite world/world.sqlite" or "PostgreSQL host/db": for messages.
  virtual const std::string& name() const = 0;
  virtual WorldInfo info() = 0;
  // info().last_seq without counting chunks or sizes: the meta row and the log's bounds.
  virtual uint64_t last_seq() { return info().last_seq; }
  // Appends the edits in one transaction, durable when it returns (fsync / commit). In the
  // same transaction, deletes the logged edits of sequence numbers [first, last] of each
  // of `forget`: appends whose outcome was in doubt (they failed, yet may have landed) and
  // whose edits the caller did not apply.
  struct SeqRange {
    uint64_t first = 0, last = 0;
  };
  // With `regions`, the stored protected regions change so, in the same transaction.
  virtual void append_edits(std::span<const LoggedEdit> edits,
                            std::span<const SeqRange> forget = {},
                            const RegionWrite* regions = nullptr) = 0;
  // The protected regions. A row that is not a valid region, or more of them than a
  // world may have, throws StoreError; a world from before regions has none.
  virtual RegionTable read_regions() = 0;
  // Writes (replaces) the chunks, records that the chunks include every edit up to
  // `checkpoint_seq`, and trims the log as `trim` says: all or nothing for readers, in
  // several short transactions (another connection's appends are not held up for long).
  // Each chunk's seq must be `checkpoint_seq`.
  virtual void write_checkpoint(std::span<const ChunkRecord> chunks, uint64_t checkpoint_seq,
                                LogTrim trim) = 0;
  virtual std::optional<ChunkRecord> read_chunk(world::ChunkCoord c) = 0;
  // Every stored chunk's coordinate and seq.
  virtual void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t seq)>& fn) = 0;
  // The logged edits after `after_seq`, in order; fn returns false to stop. A record that
  // does not decode throws StoreError naming its seq.
  virtual void for_each_edit(uint64_t after_seq,
                             const std::function<bool(const LoggedEdit&)>& fn) = 0;

  // The history (rollbacks, issue 43). Any trim of the log by write_checkpoint drops the
  // base (WorldInfo::base_seq becomes nullopt); these keep it. A store that keeps none (a
  // cluster's zones) reads no records and throws StoreError for the rest.
  // The logged edits (no rollback records) of seqs in (after_seq, through_seq], newest first.
  virtual void for_each_edit_back(uint64_t after_seq, uint64_t through_seq,
                                  const std::function<bool(const LoggedEdit&)>& fn);
  // The rollback records after `after_seq`, in order (for_each_edit gives them too).
  virtual void for_each_rollback(uint64_t after_seq,
                                 const std::function<bool(const LoggedEdit&)>& fn);
  // Chunk c as it was after edit base_seq (its record's seq is base_seq); nullopt: as the
  // generator makes it.
  virtual std::optional<ChunkRecord> read_base_chunk(world::ChunkCoord c);
  // The history's start moves to `through` (at most checkpoint_seq): `chunks`, the chunks
  // the log's edits through it changed, as of it, replace their base rows; base_seq
  // becomes `through` and the log loses everything through it. One transaction.
  virtual void advance_base(std::span<const ChunkRecord> chunks, uint64_t through);
  // The history starts again at the checkpoint: the base becomes the checkpointed chunks,
  // base_seq checkpoint_seq, and the log loses everything through it. One transaction.
  virtual void reset_base();
};

// Tools (verify, migrate): checkpointed chunk `c` read back and decoded; StoreError naming
// it when the store has no record of it or the record does not decode.
world::Chunk read_checkpointed_chunk(WorldStore& s, world::ChunkCoord c);

// `where`: a world directory (SQLite, `world.sqlite` in it; created with the directory
// when missing unless read_only) or a postgresql:// URI.
std::unique_ptr<WorldStore> open_world_store(const std::string& where, const OpenOptions& options);
bool is_postgres_uri(const std::string& where);

}  // namespace vox::store
