#include "server/store/world_backup.hpp"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <thread>

#include "server/store/sqlite_store.hpp"
#include "server/store/world_store.hpp"

namespace vox::store {

namespace fs = std::filesystem;

namespace {

// One SQLite connection, closed with its scope.
struct Db {
  sqlite3* db = nullptr;
  Db(const fs::path& file, int flags, const std::string& what) {
    if (sqlite3_open_v2(file.c_str(), &db, flags, nullptr) != SQLITE_OK) {
      const std::string why = db ? sqlite3_errmsg(db) : "out of memory";
      sqlite3_close(db);
      throw StoreError(what + ": " + file.string() + ": " + why);
    }
    sqlite3_busy_timeout(db, 5000);
  }
  ~Db() { sqlite3_close(db); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  // The first column of a statement's first row, or the error.
  std::string answer(const char* sql) {
    sqlite3_stmt* st = nullptr;
    std::string got;
    if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) == SQLITE_OK &&
        sqlite3_step(st) == SQLITE_ROW) {
      const auto* text = sqlite3_column_text(st, 0);
      got = text ? reinterpret_cast<const char*>(text) : "";
    } else {
      got = sqlite3_errmsg(db);
    }
    sqlite3_finalize(st);
    return got;
  }
  // A statement whose one answer must be `want`.
  void expect(const char* sql, const std::string& want, const std::string& what) {
    const std::string got = answer(sql);
    if (got != want) throw StoreError(what + ": " + sql + " answered '" + got + "'");
  }
  // PRAGMA quick_check: every page read and its structure checked.
  void check(const std::string& what) {
    const std::string result = answer("PRAGMA quick_check");
    if (result != "ok") throw StoreError(what + ": not a whole world file (" + result + ")");
  }
};

// Run as root: `file` takes the owner of `like` (a root-owned world would not open for
// voxeld's own user). Anyone else makes files of their own.
void owned_like(const fs::path& file, const struct stat& like) {
  if (::geteuid() != 0 || !fs::exists(file)) return;
  if (::chown(file.c_str(), like.st_uid, like.st_gid) != 0)
    throw StoreError(file.string() + ": chown: " + std::strerror(errno));
}

std::string utc_stamp() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%SZ", &tm);
  return buf;
}

void sync_file(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    throw StoreError(file.string() + ": " + std::strerror(error));
  }
  ::close(fd);
}

// Copies `from` to `to` (replaced) and syncs it.
void copy_synced(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  if (ec) throw StoreError(to.string() + ": " + ec.message());
  sync_file(to);
}

}  // namespace

BackupFigures backup_world(const std::string& world_dir, const std::string& out_file) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path source = fs::path(world_dir) / kSqliteFileName, out = out_file;
  if (!fs::exists(source))
    throw StoreError(world_dir + ": no world here (" + source.string() + " is missing)");
  if (fs::exists(out)) throw StoreError(out_file + ": exists; remove it or name another file");
  const fs::path partial = out.string() + ".partial";
  std::error_code ignored;
  fs::remove(partial, ignored);
  {
    Db from(source, SQLITE_OPEN_READONLY, "backup");
    Db to(partial, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, "backup");
    sqlite3_backup* b = sqlite3_backup_init(to.db, "main", from.db, "main");
    if (b == nullptr) throw StoreError("backup: " + std::string(sqlite3_errmsg(to.db)));
    // Every page in one step: one read transaction, so the copy is one consistent view
    // (stepping page by page restarts whenever voxeld commits, which it always does).
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    int rc = SQLITE_OK;
    while ((rc = sqlite3_backup_step(b, -1)) == SQLITE_BUSY || rc == SQLITE_LOCKED) {
      if (std::chrono::steady_clock::now() > give_up) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    sqlite3_backup_finish(b);
    if (rc != SQLITE_DONE) {
      const std::string why = sqlite3_errstr(rc);
      fs::remove(partial, ignored);
      throw StoreError("backup of " + world_dir + ": " + why);
    }
    // A self-contained file: no WAL beside it.
    to.expect("PRAGMA journal_mode=DELETE", "delete", "backup " + partial.string());
    to.check("backup " + partial.string());
  }
  // The reader may have made the world's -wal and -shm files (voxeld stopped): voxeld's.
  struct stat world_stat {};
  if (::stat(source.c_str(), &world_stat) == 0) {
    owned_like(source.string() + "-wal", world_stat);
    owned_like(source.string() + "-shm", world_stat);
  }
  sync_file(partial);
  // Into place without replacing a file made meanwhile (link fails when the name exists).
  if (::link(partial.c_str(), out.c_str()) != 0) {
    const int error = errno;
    fs::remove(partial, ignored);
    throw StoreError(out_file + ": " +
                     (error == EEXIST ? "exists; remove it or name another file"
                                      : std::string(std::strerror(error))));
  }
  fs::remove(partial, ignored);
  sync_file(out.has_parent_path() ? out.parent_path() : fs::path("."));
  return {
      .bytes = static_cast<uint64_t>(fs::file_size(out)),
      .seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
}

std::string restore_world(const std::string& backup_file, const std::string& world_dir,
                          bool replace) {
  if (is_postgres_uri(world_dir))
    throw StoreError(world_dir +
                     ": restore writes a world directory; a PostgreSQL world is "
                     "restored with pg_restore (README)");
  const fs::path from = backup_file, dir = world_dir, target = dir / kSqliteFileName;
  if (!fs::is_regular_file(from)) throw StoreError(backup_file + ": no such backup file");
  {
    Db check(from, SQLITE_OPEN_READONLY, "restore");
    check.check("restore " + backup_file);
  }
  fs::create_directories(dir);
  struct stat owner {};
  if (::stat((fs::exists(target) ? target : dir).c_str(), &owner) != 0)
    throw StoreError(world_dir + ": " + std::strerror(errno));
  // The world's writer lock: refused while a voxeld holds it, held while the files move (a
  // voxeld starting meanwhile waits, then says another process is writing the world).
  const fs::path lock_path = dir / "world.lock";
  const bool fresh_lock = !fs::exists(lock_path);
  const int lock = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock < 0) throw StoreError(lock_path.string() + ": " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{lock};
  if (fresh_lock) owned_like(lock_path, owner);
  if (::flock(lock, LOCK_EX | LOCK_NB) != 0)
    throw StoreError(world_dir + ": a voxeld is running on this world (" + lock_path.string() +
                     " is locked); stop it first");
  if (fs::exists(target) && !replace)
    throw StoreError(world_dir +
                     ": holds a world already; --force replaces it (the old one is "
                     "moved aside, not deleted)");
  // A copy beside the world, opened as a world before anything of the old one moves: a file
  // that is SQLite but no world (or a newer voxeld's) is refused here.
  const fs::path staging = dir / ".restoring";
  std::error_code ignored;
  fs::remove_all(staging, ignored);
  fs::create_directories(staging);
  const fs::path staged = staging / kSqliteFileName;
  copy_synced(from, staged);
  try {
    open_world_store(staging.string(), {.read_only = true});
  } catch (const StoreError& e) {
    fs::remove_all(staging, ignored);
    throw StoreError(backup_file + ": not a world voxeld can open: " + e.what());
  }
  fs::remove(staged.string() + "-wal", ignored);  // the check's reader leaves none, but
  fs::remove(staged.string() + "-shm", ignored);  // a stale one must not follow the file
  owned_like(staged, owner);
  // The old world moves aside whole, its WAL with it: nothing acknowledged is lost, even if
  // this process dies between the renames.
  std::string replaced;
  if (fs::exists(target)) {
    const fs::path aside = dir / ("world.replaced-" + utc_stamp());
    fs::create_directories(aside);
    owned_like(aside, owner);
    for (const char* suffix : {"-wal", "-shm", ""}) {
      const fs::path file = target.string() + suffix;
      if (fs::exists(file)) fs::rename(file, aside / file.filename());
    }
    sync_file(aside);
    replaced = aside.string();
  }
  fs::rename(staged, target);
  fs::remove_all(staging, ignored);
  sync_file(dir);
  return replaced;
}

}  // namespace vox::store
