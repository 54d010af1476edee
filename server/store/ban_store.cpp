#include "server/store/ban_store.hpp"

#include <sqlite3.h>

#include <filesystem>
#include <pqxx/pqxx>

#include "server/store/pq_errors.hpp"
#include "server/store/sqlite_statement.hpp"
#include "server/store/sqlite_store.hpp"

namespace vox::store {
namespace {

// Portable SQL (both backends number parameters $1..$7). `world` is a cluster world's name.
constexpr const char* kCreateBans =
    "CREATE TABLE IF NOT EXISTS bans (world TEXT NOT NULL, kind TEXT NOT NULL, "
    "target TEXT NOT NULL, reason TEXT NOT NULL, created_by TEXT NOT NULL, "
    "created_ms BIGINT NOT NULL, until_ms BIGINT NOT NULL, PRIMARY KEY (world, kind, target))";
constexpr const char* kSelectBans =
    "SELECT kind, target, reason, created_by, created_ms, until_ms FROM bans WHERE world = $1 "
    "ORDER BY kind, target";
constexpr const char* kDeleteEnded =
    "DELETE FROM bans WHERE world = $1 AND until_ms <> 0 AND until_ms <= $2";
constexpr const char* kUpsertBan =
    "INSERT INTO bans (world, kind, target, reason, created_by, created_ms, until_ms) "
    "VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (world, kind, target) DO UPDATE SET "
    "reason = excluded.reason, created_by = excluded.created_by, "
    "created_ms = excluded.created_ms, until_ms = excluded.until_ms";
constexpr const char* kDeleteBan =
    "DELETE FROM bans WHERE world = $1 AND kind = $2 AND target = $3";

bool has_control(const std::string& s) {
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return true;
  return false;
}

// A row read back: kept when it is a valid ban in force, counted as skipped when it is not
// a valid ban (or its times are not integers), as over past kMaxBans; true when it ended.
bool keep(BanStore::Read& out, const std::string& kind, Ban b, bool integers, int64_t now_ms) {
  if (kind == "player")
    b.kind = Ban::Kind::kPlayer;
  else if (kind == "address")
    b.kind = Ban::Kind::kAddress;
  else
    return ++out.skipped, false;
  if (!integers || ban_problem(b) || b.until_ms < 0) return ++out.skipped, false;
  if (b.expired(now_ms)) return true;
  if (out.bans.size() >= kMaxBans) return ++out.over, false;
  out.bans.push_back(std::move(b));
  return false;
}

class SqliteBans final : public BanStore {
 public:
  SqliteBans(const std::filesystem::path& file, std::string world)
      : name_("SQLite " + file.string()), world_(std::move(world)) {
    if (!std::filesystem::exists(file)) throw StoreError(name_ + ": no such world (file missing)");
    if (sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw StoreError(name_ + ": " + why);
    }
    sqlite3_busy_timeout(db_, 5000);
    Statement(db_, kCreateBans, name_).run();
  }
  ~SqliteBans() override { sqlite3_close(db_); }
  const std::string& name() const override { return name_; }

  Read read(int64_t now_ms) override {
    Read out;
    bool ended = false;
    {
      Statement q(db_, kSelectBans, name_);
      q.bind(1, world_);
      while (q.step()) {
        Ban b;
        b.target = q.text(1), b.reason = q.text(2), b.created_by = q.text(3);
        b.created_ms = q.int64(4), b.until_ms = q.int64(5);
        // A row written by hand may hold text where times belong (SQLite keeps it).
        const bool integers = q.is_integer(4) && q.is_integer(5);
        ended |= keep(out, q.text(0), std::move(b), integers, now_ms);
      }
    }
    if (ended) Statement(db_, kDeleteEnded, name_).bind(1, world_).bind(2, now_ms).run();
    return out;
  }
  void put(const Ban& b) override {
    Statement(db_, kUpsertBan, name_)
        .bind(1, world_)
        .bind(2, std::string(to_string(b.kind)))
        .bind(3, b.target)
        .bind(4, b.reason)
        .bind(5, b.created_by)
        .bind(6, b.created_ms)
        .bind(7, b.until_ms)
        .run();
  }
  bool remove(Ban::Kind kind, const std::string& target) override {
    Statement(db_, kDeleteBan, name_)
        .bind(1, world_)
        .bind(2, std::string(to_string(kind)))
        .bind(3, target)
        .run();
    return sqlite3_changes(db_) > 0;
  }

 private:
  const std::string name_, world_;
  sqlite3* db_ = nullptr;
};

class PostgresBans final : public BanStore {
 public:
  PostgresBans(std::string uri, std::string world)
      : uri_(std::move(uri)), name_("PostgreSQL " + redact_uri(uri_)), world_(std::move(world)) {
    run([](pqxx::connection&) {});  // connects and makes the table: errors at open
  }
  const std::string& name() const override { return name_; }

  Read read(int64_t now_ms) override {
    Read out;
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      bool ended = false;
      for (const auto& row : t.exec_params(kSelectBans, world_)) {
        Ban b;
        b.target = row[1].as<std::string>(), b.reason = row[2].as<std::string>();
        b.created_by = row[3].as<std::string>();
        b.created_ms = row[4].as<int64_t>(), b.until_ms = row[5].as<int64_t>();
        ended |= keep(out, row[0].as<std::string>(), std::move(b), true, now_ms);
      }
      if (ended) t.exec_params(kDeleteEnded, world_, now_ms);
      t.commit();
    });
    return out;
  }
  void put(const Ban& b) override {
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      t.exec_params(kUpsertBan, world_, std::string(to_string(b.kind)), b.target, b.reason,
                    b.created_by, b.created_ms, b.until_ms);
      t.commit();
    });
  }
  bool remove(Ban::Kind kind, const std::string& target) override {
    bool removed = false;
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      removed =
          t.exec_params(kDeleteBan, world_, std::string(to_string(kind)), target).affected_rows() >
          0;
      t.commit();
    });
    return removed;
  }

 private:
  template <class Fn>
  void run(Fn&& fn) {
    run_on(
        conn_, name_,
        [&] {
          auto c = std::make_unique<pqxx::connection>(with_connect_timeout(uri_, kWait));
          pqxx::nontransaction n(*c);
          // No statement waits long either: the keeper's stop waits for its thread.
          n.exec("SET statement_timeout = " + std::to_string(kWait.count()));
          // Nodes starting together on a new database may race to make the table: one
          // makes it, the others' CREATE fails once; then it is there.
          try {
            n.exec(kCreateBans);
          } catch (const pqxx::sql_error&) {
            n.exec(kCreateBans);
          }
          return c;
        },
        fn);
  }

  static constexpr std::chrono::milliseconds kWait{5000};
  const std::string uri_, name_, world_;
  std::unique_ptr<pqxx::connection> conn_;
};

}  // namespace

const char* to_string(Ban::Kind kind) { return kind == Ban::Kind::kPlayer ? "player" : "address"; }

std::optional<std::string> ban_problem(const Ban& b) {
  if (b.target.empty()) return std::string("a ban names a player id or an address");
  if (b.target.size() > kMaxBanTarget)
    return "a banned " + std::string(to_string(b.kind)) + " is at most " +
           std::to_string(kMaxBanTarget) + " bytes";
  if (b.reason.size() > kMaxBanReason)
    return "a ban's reason is at most " + std::to_string(kMaxBanReason) + " bytes";
  if (b.created_by.size() > kMaxBanTarget + 5)  // "name:" and a name, or a player id
    return "a ban's author is at most " + std::to_string(kMaxBanTarget + 5) + " bytes";
  if (has_control(b.target) || has_control(b.reason) || has_control(b.created_by))
    return std::string("a ban holds no control characters");
  return std::nullopt;
}

std::unique_ptr<BanStore> open_ban_store(const std::string& where, const std::string& world) {
  if (is_postgres_uri(where)) return std::make_unique<PostgresBans>(where, world);
  return std::make_unique<SqliteBans>(std::filesystem::path(where) / kSqliteFileName, world);
}

}  // namespace vox::store
