#include "server/store/sqlite_store.hpp"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <system_error>
#include <thread>

#include "server/store/edit_codec.hpp"
#include "server/store/sqlite_statement.hpp"
#include "server/store/store_schema.hpp"
#include "server/store/world_store_checks.hpp"

namespace vox::store {
namespace {

constexpr const char* kCreateTables = R"sql(
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS edit_log (seq INTEGER PRIMARY KEY, at_ms INTEGER NOT NULL,
                                     author TEXT NOT NULL, edit BLOB NOT NULL);
CREATE TABLE IF NOT EXISTS chunks (x INTEGER NOT NULL, y INTEGER NOT NULL, z INTEGER NOT NULL,
                                   seq INTEGER NOT NULL, samples BLOB NOT NULL,
                                   PRIMARY KEY (x, y, z, seq));
CREATE INDEX IF NOT EXISTS chunks_seq ON chunks (seq);
)sql";

// The statements a connection runs again and again (each append's BEGIN, INSERT and COMMIT),
// prepared once: parsing them per transaction was a fifth of the appender thread's time at
// 500 players. Keyed by the SQL's address: string literals only. Finalized before the
// connection closes. One statement serves one use at a time: a statement stepped through
// rows while a callback runs (for_each_edit, for_each_chunk) is prepared apart, since the
// callback could use the cached one. PRAGMAs stay out too: SQLite may apply a PRAGMA when
// it prepares it, so a cached `synchronous=FULL` could stop switching back.
class StatementCache {
 public:
  StatementCache() = default;
  StatementCache(const StatementCache&) = delete;
  StatementCache& operator=(const StatementCache&) = delete;
  ~StatementCache() { clear(); }

  sqlite3_stmt* get(sqlite3* db, const char* sql, const std::string& name) {
    for (const auto& [key, stmt] : entries_)
      if (key == sql) return stmt;
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v3(db, sql, -1, SQLITE_PREPARE_PERSISTENT, &stmt, nullptr) != SQLITE_OK)
      throw StoreError(name + ": " + sqlite3_errmsg(db));
    entries_.emplace_back(sql, stmt);
    return stmt;
  }
  void clear() {
    for (const auto& [key, stmt] : entries_) sqlite3_finalize(stmt);
    entries_.clear();
  }

 private:
  std::vector<std::pair<const char*, sqlite3_stmt*>> entries_;  // a dozen at most
};

class SqliteStore final : public WorldStore {
 public:
  SqliteStore(std::filesystem::path file, const OpenOptions& options)
      : file_(std::move(file)), name_("SQLite " + file_.string()) {
    const bool exists = std::filesystem::exists(file_);
    if (options.read_only && !exists) throw StoreError(name_ + ": no such world (file missing)");
    // An existing file is checked read-only first: a corrupt file, a newer schema or
    // another seed is refused before anything is written (WAL mode writes the header).
    if (exists) open(SQLITE_OPEN_READONLY), check_existing(options);
    if (options.read_only) return;
    if (options.record_start) lock_world();
    if (exists) conn_.close();
    open(SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA synchronous=FULL");
    exec("BEGIN IMMEDIATE");
    exec(kCreateTables);
    exec(schema::kCreateRegions);
    exec(schema::create_history("INTEGER", "BLOB").c_str());
    const auto meta = read_meta();
    if (!meta.contains(schema::kMetaSchemaVersion)) {
      set_meta(schema::kMetaSchemaVersion, std::to_string(kSchemaVersion));
      set_meta(schema::kMetaSeed, std::to_string(options.seed.value_or(options.new_world_seed)));
      set_meta(schema::kMetaCheckpointSeq, "0");
      set_meta(schema::kMetaBaseSeq, "0");  // a new world's history starts at its seed
    } else {
      const uint64_t version =
          parse_meta_u64(name_, schema::kMetaSchemaVersion, meta.at(schema::kMetaSchemaVersion));
      if (version < schema::kVersionedChunks)
        exec(schema::migrate_chunks("INTEGER", "BLOB").c_str());
      // Regions and the history's tables were made above; an older world has no base yet.
      if (version < static_cast<uint64_t>(kSchemaVersion))
        set_meta(schema::kMetaSchemaVersion, std::to_string(kSchemaVersion));
    }
    if (options.record_start) exec(schema::kDropUnfinishedChunks);
    const auto starts =
        meta.contains(schema::kMetaStarts)
            ? parse_meta_u64(name_, schema::kMetaStarts, meta.at(schema::kMetaStarts))
            : 0;
    if (options.record_start) set_meta(schema::kMetaStarts, std::to_string(starts + 1));
    exec("COMMIT");
  }

  const std::string& name() const override { return name_; }

  WorldInfo info() override {
    WorldInfo i = log_info();
    Statement c(conn_.db, schema::kCountVisibleChunks, name_);
    if (c.step()) i.modified_chunks = static_cast<uint64_t>(c.int64(0));
    std::error_code ec;
    for (const char* suffix : {"", "-wal"}) {
      const auto n = std::filesystem::file_size(file_.string() + suffix, ec);
      if (!ec) i.size_bytes += n;
    }
    return i;
  }

  uint64_t last_seq() override { return log_info().last_seq; }

  // The meta row and the log's bounds (logged_edits, last_seq).
  WorldInfo log_info() {
    WorldInfo i = info_from_meta(name_, read_meta());
    if (has_history()) {
      Statement q(conn_.db, schema::kLogBounds, name_);
      int64_t b[4] = {};
      bool null[4] = {};
      if (q.step())
        for (int k = 0; k < 4; ++k) b[k] = q.int64(k), null[k] = !q.is_integer(k);
      log_bounds(b, null, i);
    } else {
      Statement q(conn_.db, schema::kLogSpan, name_);
      if (q.step())
        i.logged_edits = static_cast<uint64_t>(q.int64(0)),
        i.last_seq = std::max(i.checkpoint_seq, static_cast<uint64_t>(q.int64(1)));
    }
    return i;
  }

  void append_edits(std::span<const LoggedEdit> edits, std::span<const SeqRange> forget,
                    const RegionWrite* regions) override {
    if (edits.empty() && forget.empty() && !regions) return;
    Transaction t(*this);
    Statement drop = cached("DELETE FROM edit_log WHERE seq >= ? AND seq <= ?");
    Statement drop_records = cached("DELETE FROM rollbacks WHERE seq >= ? AND seq <= ?");
    for (const SeqRange& r : forget) {
      drop.bind(1, static_cast<int64_t>(r.first)).bind(2, static_cast<int64_t>(r.last)).run();
      drop_records.bind(1, static_cast<int64_t>(r.first)).bind(2, static_cast<int64_t>(r.last));
      drop_records.run();
    }
    Statement ins = cached("INSERT INTO edit_log (seq, at_ms, author, edit) VALUES (?, ?, ?, ?)");
    Statement record =
        cached("INSERT INTO rollbacks (seq, at_ms, author, undoes) VALUES (?, ?, ?, ?)");
    for (const LoggedEdit& e : edits) {
      Statement& to = e.undoes ? record : ins;
      const auto bytes = e.undoes ? encode_seq_list(*e.undoes) : encode_edit(e.edit, e.keep);
      to.bind(1, static_cast<int64_t>(e.seq)).bind(2, e.unix_ms).bind(3, e.author).bind(4, bytes);
      to.run();
    }
    if (regions) write_regions(*regions);
    t.commit();
  }

  RegionTable read_regions() override {
    std::vector<world::Region> out;
    Statement t(conn_.db,
                "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'regions'",
                name_);
    if (!t.step() || t.int64(0) == 0) return {};  // a schema-2 world opened read-only
    Statement q(conn_.db, schema::kSelectRegions, name_);
    while (q.step()) {
      world::Region r;
      r.id = static_cast<uint64_t>(q.int64(0));
      r.name = q.text(1);
      for (int a = 0; a < 3; ++a) {
        r.box.lo[a] = static_cast<int32_t>(q.int64(2 + a));
        r.box.hi[a] = static_cast<int32_t>(q.int64(5 + a));
      }
      r.flags = static_cast<uint8_t>(q.int64(8));
      if (q.int64(8) != r.flags) r.flags = 0xff;  // refused below
      r.owners = split_owners(q.text(9));
      r.created_by = q.text(10);
      r.created_unix_ms = q.int64(11);
      out.push_back(check_stored_region(name_, std::move(r)));
    }
    const Meta meta = read_meta();
    const auto next = meta.find(schema::kMetaNextRegionId);
    return check_region_table(
        name_, std::move(out),
        next == meta.end() ? 1 : parse_meta_u64(name_, schema::kMetaNextRegionId, next->second));
  }

  void write_checkpoint(std::span<const ChunkRecord> chunks, uint64_t checkpoint_seq,
                        LogTrim trim) override {
    // Without an fsync per transaction: each holds the write lock (appends wait) only for
    // its writes. Safe because WAL frames are durable in order: the next append's fsync
    // (synchronous=FULL) covers them, and a crash of the machine before it loses the whole
    // checkpoint with its trim, never edits (the log still holds what the chunks held).
    exec("PRAGMA synchronous=NORMAL");
    {
      Synchronous full{*this};
      write_rows_and_move(chunks, checkpoint_seq, trim);
    }
    // Copies the WAL into the database now, without waiting for (or holding up) appends,
    // rather than in the append that next crosses SQLite's auto-checkpoint threshold.
    sqlite3_exec(conn_.db, "PRAGMA wal_checkpoint(PASSIVE)", nullptr, nullptr, nullptr);
  }

  std::optional<ChunkRecord> read_chunk(world::ChunkCoord c) override {
    Statement q = cached(
        "SELECT seq, samples FROM chunks WHERE x = ? AND y = ? AND z = ? AND seq <= "
        "(SELECT CAST(value AS BIGINT) FROM meta WHERE key = 'checkpoint_seq') "
        "ORDER BY seq DESC LIMIT 1");
    q.bind(1, c.x).bind(2, c.y).bind(3, c.z);
    if (!q.step()) return std::nullopt;
    const auto blob = q.blob(1);
    return ChunkRecord{c, static_cast<uint64_t>(q.int64(0)), {blob.begin(), blob.end()}};
  }

  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>& fn) override {
    Statement q(conn_.db, schema::kVisibleChunkCoords, name_);
    while (q.step()) {
      fn({static_cast<int32_t>(q.int64(0)), static_cast<int32_t>(q.int64(1)),
          static_cast<int32_t>(q.int64(2))},
         static_cast<uint64_t>(q.int64(3)));
    }
  }

  void for_each_edit(uint64_t after_seq,
                     const std::function<bool(const LoggedEdit&)>& fn) override {
    const bool history = has_history();
    Statement q(conn_.db,
                history ? VOX_LOG_UNION
                        : "SELECT seq, at_ms, author, edit, 0 FROM edit_log WHERE seq > $1 "
                          "ORDER BY seq",
                name_);
    q.bind(1, static_cast<int64_t>(after_seq));
    each_row(q, fn);
  }

  void for_each_edit_back(uint64_t after_seq, uint64_t through_seq,
                          const std::function<bool(const LoggedEdit&)>& fn) override {
    Statement q(conn_.db,
                "SELECT seq, at_ms, author, edit, 0 FROM edit_log WHERE seq > ? AND seq <= ? "
                "ORDER BY seq DESC",
                name_);
    q.bind(1, static_cast<int64_t>(after_seq));
    q.bind(2, static_cast<int64_t>(std::min<uint64_t>(through_seq, INT64_MAX)));
    each_row(q, fn);
  }

  void for_each_rollback(uint64_t after_seq,
                         const std::function<bool(const LoggedEdit&)>& fn) override {
    if (!has_history()) return;
    Statement q(conn_.db,
                "SELECT seq, at_ms, author, undoes, 1 FROM rollbacks WHERE seq > ? ORDER BY seq",
                name_);
    q.bind(1, static_cast<int64_t>(after_seq));
    each_row(q, fn);
  }

  std::optional<ChunkRecord> read_base_chunk(world::ChunkCoord c) override {
    const WorldInfo i = info_from_meta(name_, read_meta());
    if (!i.base_seq) throw StoreError(name_ + ": no history is kept (no base)");
    Statement q = cached("SELECT samples FROM chunk_base WHERE x = ? AND y = ? AND z = ?");
    q.bind(1, c.x).bind(2, c.y).bind(3, c.z);
    if (!q.step()) return std::nullopt;
    const auto blob = q.blob(0);
    return ChunkRecord{c, *i.base_seq, {blob.begin(), blob.end()}};
  }

  void advance_base(std::span<const ChunkRecord> chunks, uint64_t through) override {
    Transaction t(*this);
    const WorldInfo i = info_from_meta(name_, read_meta());
    if (!i.base_seq || through < *i.base_seq || through > i.checkpoint_seq)
      throw StoreError(name_ + ": the history cannot move to edit " + std::to_string(through));
    Statement put = cached(
        "INSERT INTO chunk_base (x, y, z, samples) VALUES (?, ?, ?, ?) "
        "ON CONFLICT (x, y, z) DO UPDATE SET samples = excluded.samples");
    for (const ChunkRecord& c : chunks) {
      put.bind(1, c.coord.x).bind(2, c.coord.y).bind(3, c.coord.z).bind(4, c.samples);
      put.run();
    }
    trim_through(through);
    set_meta(schema::kMetaBaseSeq, std::to_string(through));
    t.commit();
  }

  void reset_base() override {
    Transaction t(*this);
    const WorldInfo i = info_from_meta(name_, read_meta());
    exec("DELETE FROM chunk_base");
    exec(
        "INSERT INTO chunk_base (x, y, z, samples) SELECT x, y, z, samples FROM chunks "
        "WHERE seq <= (SELECT CAST(value AS BIGINT) FROM meta WHERE key = 'checkpoint_seq')");
    trim_through(i.checkpoint_seq);
    set_meta(schema::kMetaBaseSeq, std::to_string(i.checkpoint_seq));
    t.commit();
  }

 private:
  bool has_history() {
    Statement t(conn_.db,
                "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'rollbacks'",
                name_);
    return t.step() && t.int64(0) > 0;
  }

  // Rows of seq, at_ms, author, record, is_rollback.
  void each_row(Statement& q, const std::function<bool(const LoggedEdit&)>& fn) {
    while (q.step()) {
      LoggedEdit e;
      e.seq = static_cast<uint64_t>(q.int64(0));
      e.unix_ms = q.int64(1);
      e.author = q.text(2);
      q.int64(4) ? decode_logged_rollback(name_, q.blob(3), e)
                 : decode_logged_edit(name_, q.blob(3), e);
      if (!fn(e)) return;
    }
  }

  void trim_through(uint64_t through) {
    for (const char* sql :
         {"DELETE FROM edit_log WHERE seq <= ?", "DELETE FROM rollbacks WHERE seq <= ?"}) {
      Statement del(conn_.db, sql, name_);
      del.bind(1, static_cast<int64_t>(through)).run();
    }
  }

  // The chunk rows 64 per transaction, then the small one that makes them visible.
  void write_rows_and_move(std::span<const ChunkRecord> chunks, uint64_t checkpoint_seq,
                           const LogTrim& trim) {
    Statement put = cached(
        "INSERT INTO chunks (x, y, z, seq, samples) VALUES (?, ?, ?, ?, ?) "
        "ON CONFLICT (x, y, z, seq) DO UPDATE SET samples = excluded.samples");
    for (size_t from = 0; from < chunks.size(); from += schema::kCheckpointPart) {
      Transaction t(*this);
      for (const ChunkRecord& c :
           chunks.subspan(from, std::min(schema::kCheckpointPart, chunks.size() - from))) {
        put.bind(1, c.coord.x).bind(2, c.coord.y).bind(3, c.coord.z);
        put.bind(4, static_cast<int64_t>(checkpoint_seq)).bind(5, c.samples);
        put.run();
      }
      t.commit();
    }
    Transaction t(*this);  // the move: readers see the new rows from here on
    Statement rows(conn_.db, (std::string(schema::kCountRowsOfSeq) + "?").c_str(), name_);
    rows.bind(1, static_cast<int64_t>(checkpoint_seq));
    if (!rows.step() || static_cast<size_t>(rows.int64(0)) != distinct_coords(chunks))
      throw StoreError(name_ + ": checkpoint " + std::to_string(checkpoint_seq) +
                       " lost rows while written (another writer?); not recorded");
    rows.reset();  // read through: no statement of this transaction is left open at COMMIT
    const uint64_t previous = info_from_meta(name_, read_meta()).checkpoint_seq;
    Statement old = cached("DELETE FROM chunks WHERE x = ? AND y = ? AND z = ? AND seq < ?");
    for (const ChunkRecord& c : chunks) {
      old.bind(1, c.coord.x).bind(2, c.coord.y).bind(3, c.coord.z);
      old.bind(4, static_cast<int64_t>(checkpoint_seq)).run();
    }
    // Rows of checkpoints that failed after `previous` (their chunks are in this one).
    Statement failed(conn_.db, "DELETE FROM chunks WHERE seq > ? AND seq < ?", name_);
    failed.bind(1, static_cast<int64_t>(previous)).bind(2, static_cast<int64_t>(checkpoint_seq));
    failed.run();
    set_meta(schema::kMetaCheckpointSeq, std::to_string(checkpoint_seq));
    if (trim.through > 0) {
      Statement del(conn_.db, trim.windowed() ? schema::kTrimLog : schema::kTrimLogAll, name_);
      del.bind(1, static_cast<int64_t>(trim.through));
      if (trim.windowed()) del.bind(2, trim.accepted_before_ms).bind(3, trim.stamps_until_ms);
      del.run();
      // The records before the first edit kept go with them, and the history's base.
      Statement records(conn_.db,
                        "DELETE FROM rollbacks WHERE seq <= ? AND seq < COALESCE((SELECT "
                        "MIN(seq) FROM edit_log), ?)",
                        name_);
      records.bind(1, static_cast<int64_t>(trim.through))
          .bind(2, static_cast<int64_t>(trim.through) + 1)
          .run();
      exec(schema::kDropBase);
    }
    t.commit();
  }

  class Transaction {
   public:
    explicit Transaction(SqliteStore& s) : s_(s) { s_.cached("BEGIN IMMEDIATE").run(); }
    ~Transaction() {
      if (!done_) sqlite3_exec(s_.conn_.db, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
      s_.cached("COMMIT").run();
      done_ = true;
    }

   private:
    SqliteStore& s_;
    bool done_ = false;
  };

  // Puts synchronous=FULL back when a write_checkpoint ends (or throws).
  struct Synchronous {
    SqliteStore& s;
    ~Synchronous() {
      sqlite3_exec(s.conn_.db, "PRAGMA synchronous=FULL", nullptr, nullptr, nullptr);
    }
  };

  void open(int flags) {
    const int rc = sqlite3_open_v2(file_.c_str(), &conn_.db, flags | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
      const std::string why = conn_.db ? sqlite3_errmsg(conn_.db) : sqlite3_errstr(rc);
      sqlite3_close(conn_.db);
      conn_.db = nullptr;
      throw StoreError(name_ + ": " + why);
    }
    sqlite3_busy_handler(conn_.db, &SqliteStore::on_busy, &busy_since_);
  }

  // Waiting for the other connection's write lock (the checkpoint writer's, or the
  // appender's): SQLite's own busy timeout sleeps 1, 2, 5, 10, 15, 20 ... ms between
  // tries, so an append blocked for 3 ms waited 8; this one tries every 250 us, up to 5 s.
  static int on_busy(void* since, int tries) {
    auto& start = *static_cast<std::chrono::steady_clock::time_point*>(since);
    const auto now = std::chrono::steady_clock::now();
    if (tries == 0) start = now;
    if (now - start >= kBusyTimeout) return 0;  // SQLITE_BUSY to the caller
    std::this_thread::sleep_for(std::chrono::microseconds(250));
    return 1;
  }
  static constexpr auto kBusyTimeout = std::chrono::seconds(5);

  void check_existing(const OpenOptions& options) {
    std::string result;
    try {
      Statement q(conn_.db, options.record_start ? "PRAGMA quick_check" : "PRAGMA schema_version",
                  name_);
      if (q.step()) result = options.record_start ? q.text(0) : "ok";
    } catch (const StoreError& e) {
      throw StoreError(std::string(e.what()) + " (corrupt or not a voxeld world)");
    }
    if (result != "ok") throw StoreError(name_ + ": corrupt: " + result);
    Statement t(conn_.db,
                "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'meta'", name_);
    if (!t.step() || t.int64(0) == 0) {
      Statement any(conn_.db, "SELECT COUNT(*) FROM sqlite_master", name_);
      if (any.step() && any.int64(0) > 0) throw StoreError(name_ + ": not a voxeld world");
      return;  // an empty database file: made into a world
    }
    check_meta(name_, read_meta(), options);
  }

  void write_regions(const RegionWrite& w) {
    if (w.whole) exec("DELETE FROM regions");
    Statement ins(conn_.db, schema::kInsertRegion, name_);
    for (const world::Region& r : w.upsert) {
      ins.bind(1, static_cast<int64_t>(r.id)).bind(2, r.name);
      for (int a = 0; a < 3; ++a) ins.bind(3 + a, r.box.lo[a]).bind(6 + a, r.box.hi[a]);
      ins.bind(9, int64_t{r.flags}).bind(10, join_owners(r.owners)).bind(11, r.created_by);
      ins.bind(12, r.created_unix_ms).run();
    }
    Statement del(conn_.db, "DELETE FROM regions WHERE id = ?", name_);
    for (const uint64_t id : w.remove) del.bind(1, static_cast<int64_t>(id)).run();
    set_meta(schema::kMetaNextRegionId, std::to_string(w.next_id));
  }

  // A statement of the connection's cache, reset when it goes. Takes string literals only:
  // the cache knows a statement by its SQL's address, which a built string could reuse.
  template <size_t N>
  Statement cached(const char (&sql)[N]) {
    return Statement(conn_.cache.get(conn_.db, sql, name_), name_);
  }

  void exec(const char* sql) {
    char* error = nullptr;
    if (sqlite3_exec(conn_.db, sql, nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string why = error ? error : sqlite3_errmsg(conn_.db);
      sqlite3_free(error);
      throw StoreError(name_ + ": " + why);
    }
  }

  Meta read_meta() {
    Meta meta;
    Statement q = cached("SELECT key, value FROM meta");
    while (q.step()) meta[q.text(0)] = q.text(1);
    return meta;
  }

  void set_meta(const char* key, const std::string& value) {
    Statement q = cached(
        "INSERT INTO meta (key, value) VALUES (?, ?) "
        "ON CONFLICT (key) DO UPDATE SET value = excluded.value");
    q.bind(1, std::string(key)).bind(2, value).run();
  }

  std::filesystem::path file_;
  std::string name_;
  std::chrono::steady_clock::time_point busy_since_;  // on_busy's, per connection
  // Closed by its destructor, so also when the constructor throws (a refused file).
  // One writing process per world: an exclusive flock on world.lock beside the file, held
  // while this connection lives (the kernel drops it when the process dies, even kill -9).
  // A writer still closing gets kWriterLockWait to let go, as with PostgreSQL.
  void lock_world() {
    const std::filesystem::path path = file_.parent_path() / "world.lock";
    lock_fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (lock_fd_ < 0) throw StoreError(name_ + ": " + path.string() + ": " + std::strerror(errno));
    const auto give_up = std::chrono::steady_clock::now() + kWriterLockWait;
    int locked = -1;
    while ((locked = ::flock(lock_fd_, LOCK_EX | LOCK_NB)) != 0 && errno == EWOULDBLOCK &&
           std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (locked != 0) {
      const int error = errno;
      ::close(lock_fd_);
      lock_fd_ = -1;
      throw StoreError(name_ + ": " +
                       (error == EWOULDBLOCK ? "another voxeld is writing this world (" +
                                                   path.string() + " is locked); stop it first"
                                             : path.string() + ": " + std::strerror(error)));
    }
  }

  struct LockFile {
    int& fd;
    ~LockFile() {
      if (fd >= 0) ::close(fd);
    }
  };

  int lock_fd_ = -1;
  LockFile lock_file_{lock_fd_};

  struct Connection {
    sqlite3* db = nullptr;
    Connection() = default;
    Connection(const Connection&) = delete;
    Connection& operator=(const Connection&) = delete;
    StatementCache cache;  // finalized before the connection closes
    ~Connection() { close(); }
    void close() {
      cache.clear();
      sqlite3_close(db);
      db = nullptr;
    }
  } conn_;  // declared after the lock: closed before it is released
};

}  // namespace

std::unique_ptr<WorldStore> open_sqlite_store(const std::filesystem::path& dir,
                                              const OpenOptions& options) {
  if (!options.read_only) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw StoreError("world directory " + dir.string() + ": " + ec.message());
  }
  return std::make_unique<SqliteStore>(dir / kSqliteFileName, options);
}

}  // namespace vox::store
