// What both backends keep, in portable SQL (INSERT ... ON CONFLICT, no vendor types in the
// statements), so the PostgreSQL one also runs on PostgreSQL-compatible databases. The
// tables differ only in their column types (BLOB/BYTEA, INTEGER/BIGINT).
//
//   meta      key TEXT PRIMARY KEY, value TEXT: schema_version, seed, starts, checkpoint_seq
//   edit_log  seq PRIMARY KEY, at_ms, author TEXT, edit (edit_codec.hpp)
//   chunks    (x, y, z) PRIMARY KEY, seq, samples (chunk_codec.hpp)
#pragma once

namespace vox::store::schema {

inline constexpr const char* kMetaSchemaVersion = "schema_version";
inline constexpr const char* kMetaSeed = "seed";
inline constexpr const char* kMetaStarts = "starts";
inline constexpr const char* kMetaCheckpointSeq = "checkpoint_seq";

}  // namespace vox::store::schema
