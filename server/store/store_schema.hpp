// What both backends keep, in portable SQL (INSERT ... ON CONFLICT, no vendor types in the
// statements), so the PostgreSQL one also runs on PostgreSQL-compatible databases. The
// tables differ only in their column types (BLOB/BYTEA, INTEGER/BIGINT).
//
//   meta      key TEXT PRIMARY KEY, value TEXT: schema_version, seed, starts, checkpoint_seq
//   edit_log  seq PRIMARY KEY, at_ms, author TEXT, edit (edit_codec.hpp)
//   chunks    (x, y, z, seq) PRIMARY KEY, samples (chunk_codec.hpp); index on seq
//   rollbacks seq PRIMARY KEY, at_ms, author, undoes (edit_codec.hpp's seq list): rollback
//             records, numbered with the log's edits (schema 4)
//   chunk_base (x, y, z) PRIMARY KEY, samples: each chunk the log's trimmed edits changed,
//             as of meta base_seq (absent: no base kept); the history rollbacks reach
//             (schema 4)
//   regions   id PRIMARY KEY, name, x0 y0 z0 x1 y1 z1 (inclusive), flags, owners (player
//             ids joined by '\n'; ids hold no control characters), created_by, created_ms
//             (schema 3: protected regions, world/region.hpp; written whole by the append
//             that changes them)
//
// Chunk rows are versioned (schema 2): a checkpoint at sequence S writes its chunks as rows
// of seq S in several short transactions, then one short transaction moves checkpoint_seq
// to S, deletes the rows they supersede and trims the log. Readers see, per chunk, its row
// of seq <= checkpoint_seq (there is at most one once the move committed): a checkpoint is
// all or nothing, yet never holds the write lock for long. Rows above checkpoint_seq are an
// unfinished checkpoint's, deleted when a writer opens the store. Schema 1 (one row per
// chunk) is migrated when a writer opens it.
#pragma once

#include <cstddef>
#include <string>

namespace vox::store::schema {

inline constexpr int kVersionedChunks = 2;  // the schema that made chunk rows versioned
inline constexpr int kRegions = 3;          // the schema that added protected regions
inline constexpr int kHistory = 4;          // rollback records and the history's base

// A region table's columns (a cluster world keeps the same in `zone_regions`, zone_schema.hpp).
// Portable as it is: SQLite gives BIGINT columns integer affinity.
#define VOX_REGION_TABLE                                                                    \
  "(id BIGINT PRIMARY KEY, name TEXT NOT NULL, "                                            \
  "x0 INTEGER NOT NULL, y0 INTEGER NOT NULL, z0 INTEGER NOT NULL, "                         \
  "x1 INTEGER NOT NULL, y1 INTEGER NOT NULL, z1 INTEGER NOT NULL, flags INTEGER NOT NULL, " \
  "owners TEXT NOT NULL, created_by TEXT NOT NULL, created_ms BIGINT NOT NULL)"
#define VOX_REGION_COLUMNS "id, name, x0, y0, z0, x1, y1, z1, flags, owners, created_by, created_ms"
// Both backends number parameters $1..$12 (SQLite binds them by position).
#define VOX_REGION_VALUES "VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)"
inline constexpr const char* kCreateRegions =
    "CREATE TABLE IF NOT EXISTS regions " VOX_REGION_TABLE ";";
inline constexpr const char* kInsertRegion =
    "INSERT INTO regions (" VOX_REGION_COLUMNS ") " VOX_REGION_VALUES;
inline constexpr const char* kSelectRegions =
    "SELECT " VOX_REGION_COLUMNS " FROM regions ORDER BY id";
// How many edits the log holds (WorldInfo::logged_edits) and its last seq: by its first
// and last keys, not a count, which would read a week of history at every start. The log
// is one contiguous tail but where an append in doubt was forgotten (a gap of its edits).
inline constexpr const char* kLogSpan =
    "SELECT COALESCE(MAX(seq) - MIN(seq) + 1, 0), COALESCE(MAX(seq), 0) FROM edit_log";
// A checkpoint's trim of the log (LogTrim): $1 through, $2 accepted_before_ms. The first
// edit kept is found from the oldest on (the rows about to go, then one): no index on at_ms.
// A stamp past $3 (a clock that ran ahead) does not hold the log back.
inline constexpr const char* kTrimLog =
    "DELETE FROM edit_log WHERE seq <= $1 AND seq < COALESCE((SELECT seq FROM edit_log "
    "WHERE at_ms >= $2 AND at_ms <= $3 ORDER BY seq LIMIT 1), CAST($1 AS BIGINT) + 1)";
inline constexpr const char* kTrimLogAll = "DELETE FROM edit_log WHERE seq <= $1";
// The log's first and last keys, of edits and of rollback records (each by its index).
inline constexpr const char* kLogBounds =
    "SELECT (SELECT MIN(seq) FROM edit_log), (SELECT MAX(seq) FROM edit_log), "
    "(SELECT MIN(seq) FROM rollbacks), (SELECT MAX(seq) FROM rollbacks)";
// The log in order, edits and rollback records merged ($1: after): seq, at_ms, author,
// record, is_rollback.
#define VOX_LOG_UNION                                                          \
  "SELECT seq, at_ms, author, edit, 0 FROM edit_log WHERE seq > $1 UNION ALL " \
  "SELECT seq, at_ms, author, undoes, 1 FROM rollbacks WHERE seq > $1 ORDER BY seq"
inline constexpr const char* kDropBase =
    "DELETE FROM chunk_base; DELETE FROM meta WHERE key = 'base_seq';";
// Chunk rows per transaction while a checkpoint writes (about 0.8 MB).
inline constexpr size_t kCheckpointPart = 64;

// The visible checkpoint, inside a statement (both backends cast TEXT to BIGINT alike).
#define VOX_CHECKPOINT_SEQ "(SELECT CAST(value AS BIGINT) FROM meta WHERE key = 'checkpoint_seq')"
inline constexpr const char* kCountVisibleChunks =
    "SELECT COUNT(*) FROM chunks WHERE seq <= " VOX_CHECKPOINT_SEQ;
inline constexpr const char* kVisibleChunkCoords =
    "SELECT x, y, z, seq FROM chunks WHERE seq <= " VOX_CHECKPOINT_SEQ;
inline constexpr const char* kDropUnfinishedChunks =
    "DELETE FROM chunks WHERE seq > " VOX_CHECKPOINT_SEQ;
// The move's check that every row it is about to make visible is there (a second writer,
// were one to get in, could have deleted them as unfinished).
inline constexpr const char* kCountRowsOfSeq = "SELECT COUNT(*) FROM chunks WHERE seq = ";
#undef VOX_CHECKPOINT_SEQ

// Schema 1 -> 2: chunk rows keyed by (x, y, z, seq), in the backend's column types.
inline std::string migrate_chunks(const std::string& int64_type, const std::string& blob_type) {
  return "CREATE TABLE chunks_v2 (x INTEGER NOT NULL, y INTEGER NOT NULL, z INTEGER NOT NULL, "
         "seq " +
         int64_type + " NOT NULL, samples " + blob_type +
         " NOT NULL, "
         "PRIMARY KEY (x, y, z, seq));"
         "INSERT INTO chunks_v2 (x, y, z, seq, samples) SELECT x, y, z, seq, samples FROM chunks;"
         "DROP TABLE chunks;"
         "ALTER TABLE chunks_v2 RENAME TO chunks;"
         "CREATE INDEX chunks_seq ON chunks (seq);";
}

inline constexpr const char* kMetaSchemaVersion = "schema_version";
inline constexpr const char* kMetaSeed = "seed";
inline constexpr const char* kMetaStarts = "starts";
inline constexpr const char* kMetaCheckpointSeq = "checkpoint_seq";
inline constexpr const char* kMetaNextRegionId = "next_region_id";
inline constexpr const char* kMetaBaseSeq = "base_seq";

// The history's tables, in a backend's column types.
inline std::string create_history(const std::string& int64_type, const std::string& blob_type) {
  return "CREATE TABLE IF NOT EXISTS rollbacks (seq " + int64_type + " PRIMARY KEY, at_ms " +
         int64_type + " NOT NULL, author TEXT NOT NULL, undoes " + blob_type +
         " NOT NULL);"
         "CREATE TABLE IF NOT EXISTS chunk_base (x INTEGER NOT NULL, y INTEGER NOT NULL, "
         "z INTEGER NOT NULL, samples " +
         blob_type + " NOT NULL, PRIMARY KEY (x, y, z));";
}

}  // namespace vox::store::schema
