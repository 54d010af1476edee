// A PostgreSQL world backed up to a file (voxel-cli world backup postgresql://... --out
// FILE): one repeatable-read transaction's view of its tables, written as a new SQLite
// world, row for row (the log's and chunks' bytes as stored), into one self-contained file
// that `world restore` and `world verify` take like any SQLite backup.
#include <sqlite3.h>

#include <chrono>
#include <filesystem>
#include <pqxx/pqxx>

#include "server/store/ban_store.hpp"
#include "server/store/pq_errors.hpp"
#include "server/store/sqlite_statement.hpp"
#include "server/store/sqlite_store.hpp"
#include "server/store/store_schema.hpp"
#include "server/store/world_backup.hpp"
#include "server/store/world_store_checks.hpp"

namespace vox::store {
namespace {

namespace fs = std::filesystem;

constexpr size_t kFetch = 256;  // rows per FETCH: a few MB of chunks at most

std::span<const uint8_t> bytes_of(const pqxx::binarystring& b) {
  return {reinterpret_cast<const uint8_t*>(b.data()), b.size()};
}

// Runs `sql` through a cursor, `fn` on each row, kFetch rows at a time.
template <class Fn>
void each_row(pqxx::transaction_base& t, const std::string& cursor, const std::string& sql,
              Fn&& fn) {
  t.exec("DECLARE " + cursor + " NO SCROLL CURSOR FOR " + sql);
  for (;;) {
    const pqxx::result rows = t.exec("FETCH " + std::to_string(kFetch) + " FROM " + cursor);
    for (const auto& row : rows) fn(row);
    if (rows.size() < kFetch) break;
  }
  t.exec("CLOSE " + cursor);
}

bool has_table(pqxx::transaction_base& t, const char* table) {
  return t.exec1(std::string("SELECT to_regclass('") + table + "') IS NOT NULL")[0].as<bool>();
}

struct SqliteFile {
  sqlite3* db = nullptr;
  explicit SqliteFile(const fs::path& file) {
    if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
      const std::string why = db ? sqlite3_errmsg(db) : "out of memory";
      sqlite3_close(db);
      throw StoreError("backup " + file.string() + ": " + why);
    }
  }
  ~SqliteFile() { sqlite3_close(db); }
  SqliteFile(const SqliteFile&) = delete;
  SqliteFile& operator=(const SqliteFile&) = delete;
};

}  // namespace

BackupFigures backup_postgres_world(const std::string& uri, const std::string& out_file) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path out = out_file, partial = out.string() + ".partial.d";
  if (fs::exists(out)) throw StoreError(out_file + ": exists; remove it or name another file");
  std::error_code ignored;
  fs::remove_all(partial, ignored);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{partial};
  const std::string name = "PostgreSQL " + redact_uri(uri);
  translate_pq_errors(
      name, [] {},
      [&] {
        pqxx::connection c(with_connect_timeout(uri, std::chrono::seconds(10)));
        pqxx::transaction<pqxx::isolation_level::repeatable_read, pqxx::readwrite_policy::read_only>
            t(c);
        if (!has_table(t, "meta")) throw StoreError(name + ": no world here");
        Meta meta;
        for (const auto& row : t.exec("SELECT key, value FROM meta"))
          meta[row[0].as<std::string>()] = row[1].as<std::string>();
        check_meta(name, meta, OpenOptions{.read_only = true});
        const WorldInfo info = info_from_meta(name, meta);
        // The new world, made by the SQLite backend (its schema, this seed), then filled.
        open_world_store(partial.string(), {.seed = info.seed});
        SqliteFile to(partial / kSqliteFileName);
        const std::string to_name = "backup " + (partial / kSqliteFileName).string();
        Statement(to.db, "BEGIN", to_name).run();
        Statement put_meta(to.db,
                           "INSERT INTO meta (key, value) VALUES (?, ?) ON CONFLICT (key) DO "
                           "UPDATE SET value = excluded.value",
                           to_name);
        // The base is the source's, or none (a new file's says its history starts at 0).
        Statement(to.db, "DELETE FROM meta WHERE key = 'base_seq'", to_name).run();
        for (const auto& [key, value] : meta) put_meta.bind(1, key).bind(2, value).run();
        Statement put_chunk(
            to.db, "INSERT INTO chunks (x, y, z, seq, samples) VALUES (?, ?, ?, ?, ?)", to_name);
        each_row(t, "vox_chunks",
                 "SELECT x, y, z, seq, samples FROM chunks WHERE seq <= " +
                     std::to_string(info.checkpoint_seq),
                 [&](const pqxx::row& r) {
                   const pqxx::binarystring samples(r[4]);
                   put_chunk.bind(1, r[0].as<int64_t>()).bind(2, r[1].as<int64_t>());
                   put_chunk.bind(3, r[2].as<int64_t>()).bind(4, r[3].as<int64_t>());
                   put_chunk.bind(5, bytes_of(samples)).run();
                 });
        Statement put_edit(
            to.db, "INSERT INTO edit_log (seq, at_ms, author, edit) VALUES (?, ?, ?, ?)", to_name);
        each_row(t, "vox_log", "SELECT seq, at_ms, author, edit FROM edit_log ORDER BY seq",
                 [&](const pqxx::row& r) {
                   const pqxx::binarystring edit(r[3]);
                   put_edit.bind(1, r[0].as<int64_t>()).bind(2, r[1].as<int64_t>());
                   put_edit.bind(3, r[2].as<std::string>()).bind(4, bytes_of(edit)).run();
                 });
        if (has_table(t, "rollbacks")) {
          Statement put_record(
              to.db, "INSERT INTO rollbacks (seq, at_ms, author, undoes) VALUES (?, ?, ?, ?)",
              to_name);
          each_row(t, "vox_records", "SELECT seq, at_ms, author, undoes FROM rollbacks",
                   [&](const pqxx::row& r) {
                     const pqxx::binarystring undoes(r[3]);
                     put_record.bind(1, r[0].as<int64_t>()).bind(2, r[1].as<int64_t>());
                     put_record.bind(3, r[2].as<std::string>()).bind(4, bytes_of(undoes)).run();
                   });
          Statement put_base(to.db, "INSERT INTO chunk_base (x, y, z, samples) VALUES (?, ?, ?, ?)",
                             to_name);
          each_row(t, "vox_base", "SELECT x, y, z, samples FROM chunk_base",
                   [&](const pqxx::row& r) {
                     const pqxx::binarystring samples(r[3]);
                     put_base.bind(1, r[0].as<int64_t>()).bind(2, r[1].as<int64_t>());
                     put_base.bind(3, r[2].as<int64_t>()).bind(4, bytes_of(samples)).run();
                   });
        }
        if (has_table(t, "regions")) {
          Statement put_region(to.db, schema::kInsertRegion, to_name);
          for (const auto& r : t.exec(schema::kSelectRegions)) {
            for (int i = 0; i < 12; ++i) {
              if (i == 1 || i == 9 || i == 10)
                put_region.bind(i + 1, r[i].as<std::string>());
              else
                put_region.bind(i + 1, r[i].as<int64_t>());
            }
            put_region.run();
          }
        }
        Statement(to.db, "COMMIT", to_name).run();
        if (has_table(t, "bans")) {  // a single node's bans (world ''), as stored
          auto bans = open_ban_store(partial.string());
          for (const auto& r :
               t.exec("SELECT kind, target, reason, created_by, created_ms, until_ms FROM bans "
                      "WHERE world = ''")) {
            Ban b;
            b.kind = r[0].as<std::string>() == "address" ? Ban::Kind::kAddress : Ban::Kind::kPlayer;
            b.target = r[1].as<std::string>(), b.reason = r[2].as<std::string>();
            b.created_by = r[3].as<std::string>();
            b.created_ms = r[4].as<int64_t>(), b.until_ms = r[5].as<int64_t>();
            bans->put(b);
          }
        }
        t.commit();
        // A self-contained file: no WAL beside it.
        Statement(to.db, "PRAGMA journal_mode=DELETE", to_name).run();
      });
  // The SQLite world checks itself on open (its pages whole); then it becomes the file.
  open_world_store(partial.string(), {.read_only = true})->info();
  fs::rename(partial / kSqliteFileName, out);
  BackupFigures f;
  f.bytes = fs::file_size(out);
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

}  // namespace vox::store
