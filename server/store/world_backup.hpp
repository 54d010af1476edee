// A world directory's backup while voxeld runs, and its restore (voxel-cli world backup |
// restore). The backup is SQLite's online backup API over the world's file: one read
// transaction's consistent view (every edit committed before it began, none half), taken
// beside voxeld, whose appends go on meanwhile (WAL: readers do not block writers). A
// PostgreSQL world is backed up to the same kind of file (backup_postgres_world), or with
// pg_dump (README). Throws StoreError; any thread.
#pragma once

#include <cstdint>
#include <string>

namespace vox::store {

struct BackupFigures {
  uint64_t bytes = 0;
  double seconds = 0;
};

// Writes `out_file` (refused when it exists), a single SQLite file holding the world of
// `world_dir` as one transaction saw it; written under a temporary name, synced, then
// renamed, so a failed or interrupted backup leaves no file that looks whole.
BackupFigures backup_world(const std::string& world_dir, const std::string& out_file);
// The same file from a PostgreSQL world (a single node's, not a cluster's): one
// repeatable-read transaction's view of its tables, written row for row as a SQLite world
// (pg_export.cpp). Restored with restore_world into a directory like any backup.
BackupFigures backup_postgres_world(const std::string& uri, const std::string& out_file);

// Puts `backup_file` in place as the world of `world_dir` (created when missing), once a
// copy of it beside the world has been opened as a world (its pages whole, its schema and
// seed read). A directory already holding a world is refused unless `replace`; then the
// world it held is moved aside, whole (its WAL with it), into world.replaced-TIME/, whose
// path is returned (empty: there was none). One a running voxeld holds (its world.lock) is
// always refused. Run as root, the files take the owner of the world they replace (or of
// the directory), so that voxeld's own user can open them.
std::string restore_world(const std::string& backup_file, const std::string& world_dir,
                          bool replace);

}  // namespace vox::store
