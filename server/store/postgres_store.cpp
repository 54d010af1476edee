#include "server/store/postgres_store.hpp"

#include <algorithm>
#include <chrono>
#include <pqxx/pqxx>
#include <thread>

#include "server/store/edit_codec.hpp"
#include "server/store/pq_errors.hpp"
#include "server/store/pq_regions.hpp"
#include "server/store/store_schema.hpp"
#include "server/store/world_store_checks.hpp"

namespace vox::store {
namespace {

constexpr const char* kCreateTables = R"sql(
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS edit_log (seq BIGINT PRIMARY KEY, at_ms BIGINT NOT NULL,
                                     author TEXT NOT NULL, edit BYTEA NOT NULL);
CREATE TABLE IF NOT EXISTS chunks (x INTEGER NOT NULL, y INTEGER NOT NULL, z INTEGER NOT NULL,
                                   seq BIGINT NOT NULL, samples BYTEA NOT NULL,
                                   PRIMARY KEY (x, y, z, seq));
CREATE INDEX IF NOT EXISTS chunks_seq ON chunks (seq);
)sql";

constexpr const char* kUpsertMeta =
    "INSERT INTO meta (key, value) VALUES ($1, $2) "
    "ON CONFLICT (key) DO UPDATE SET value = excluded.value";

pqxx::binarystring binary(std::span<const uint8_t> bytes) {
  return pqxx::binarystring(bytes.data(), bytes.size());
}

Meta read_meta(pqxx::transaction_base& t) {
  Meta meta;
  for (const auto& row : t.exec("SELECT key, value FROM meta"))
    meta[row[0].as<std::string>()] = row[1].as<std::string>();
  return meta;
}

bool has_meta_table(pqxx::transaction_base& t) {
  return t.exec1("SELECT to_regclass('meta') IS NOT NULL")[0].as<bool>();
}

class PostgresStore final : public WorldStore {
 public:
  PostgresStore(std::string uri, const OpenOptions& options)
      : uri_(std::move(uri)), name_("PostgreSQL " + redact_uri(uri_)), options_(options) {
    open();
  }
  // The writer lets go of the world's lock before closing: the next writer need not wait
  // for the backend to notice the close (best effort; the close drops it anyway).
  ~PostgresStore() override {
    if (!conn_ || !conn_->is_open() || options_.read_only || !options_.record_start) return;
    try {
      pqxx::nontransaction t(*conn_);
      t.exec("SELECT pg_advisory_unlock_all()");
    } catch (const std::exception&) {
    }
  }

 private:
  void open() {
    run([&](pqxx::connection& c) {
      if (options_.read_only) {
        pqxx::read_transaction t(c);
        if (!has_meta_table(t)) throw StoreError(name_ + ": no world in this database");
        check_meta(name_, read_meta(t), options_);
        return;
      }
      pqxx::work t(c);
      // One opener at a time sets the world up (several voxeld may share it).
      t.exec("SELECT pg_advisory_xact_lock(7007)");
      if (has_meta_table(t)) check_meta(name_, read_meta(t), options_);
      const Meta before = has_meta_table(t) ? read_meta(t) : Meta{};
      const bool migrate =
          before.contains(schema::kMetaSchemaVersion) &&
          parse_meta_u64(name_, schema::kMetaSchemaVersion, before.at(schema::kMetaSchemaVersion)) <
              schema::kVersionedChunks;
      if (migrate) {
        t.exec(schema::migrate_chunks("BIGINT", "BYTEA") +
               "ALTER INDEX chunks_v2_pkey RENAME TO chunks_pkey;");  // as a new world names it
        t.exec_params(kUpsertMeta, schema::kMetaSchemaVersion, std::to_string(kSchemaVersion));
      }
      t.exec(kCreateTables);
      t.exec(schema::kCreateRegions);
      t.exec(schema::create_history("BIGINT", "BYTEA"));
      const Meta meta = read_meta(t);
      // Regions and the history's tables were made above; an older world has no base yet.
      if (meta.contains(schema::kMetaSchemaVersion) &&
          parse_meta_u64(name_, schema::kMetaSchemaVersion, meta.at(schema::kMetaSchemaVersion)) <
              static_cast<uint64_t>(kSchemaVersion))
        t.exec_params(kUpsertMeta, schema::kMetaSchemaVersion, std::to_string(kSchemaVersion));
      if (!meta.contains(schema::kMetaSchemaVersion)) {
        t.exec_params(kUpsertMeta, schema::kMetaSchemaVersion, std::to_string(kSchemaVersion));
        t.exec_params(kUpsertMeta, schema::kMetaSeed,
                      std::to_string(options_.seed.value_or(options_.new_world_seed)));
        t.exec_params(kUpsertMeta, schema::kMetaCheckpointSeq, "0");
        t.exec_params(kUpsertMeta, schema::kMetaBaseSeq, "0");
      }
      if (options_.record_start) t.exec(schema::kDropUnfinishedChunks);
      const uint64_t starts =
          meta.contains(schema::kMetaStarts)
              ? parse_meta_u64(name_, schema::kMetaStarts, meta.at(schema::kMetaStarts))
              : 0;
      if (options_.record_start)
        t.exec_params(kUpsertMeta, schema::kMetaStarts, std::to_string(starts + 1));
      t.commit();
    });
  }

 public:
  const std::string& name() const override { return name_; }

  WorldInfo info() override {
    WorldInfo i;
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      i = log_info(t);
      i.modified_chunks = t.exec1(schema::kCountVisibleChunks)[0].as<uint64_t>();
      i.size_bytes = t.exec1(
                          "SELECT pg_total_relation_size('meta') + "
                          "pg_total_relation_size('edit_log') + pg_total_relation_size('chunks') + "
                          "COALESCE(pg_total_relation_size(to_regclass('regions')), 0)")[0]
                         .as<uint64_t>();
    });
    return i;
  }

  uint64_t last_seq() override {
    uint64_t seq = 0;
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      seq = log_info(t).last_seq;
    });
    return seq;
  }

  // The meta row and the log's bounds (logged_edits, last_seq).
  WorldInfo log_info(pqxx::read_transaction& t) {
    WorldInfo i = info_from_meta(name_, read_meta(t));
    if (has_history(t)) {
      const auto log = t.exec1(schema::kLogBounds);
      int64_t b[4] = {};
      bool null[4] = {};
      for (int k = 0; k < 4; ++k)
        null[k] = log[k].is_null(), b[k] = null[k] ? 0 : log[k].as<int64_t>();
      log_bounds(b, null, i);
    } else {
      const auto log = t.exec1(schema::kLogSpan);
      i.logged_edits = log[0].as<uint64_t>();
      i.last_seq = std::max(i.checkpoint_seq, log[1].as<uint64_t>());
    }
    return i;
  }

  void append_edits(std::span<const LoggedEdit> edits, std::span<const SeqRange> forget,
                    const RegionWrite* regions) override {
    refuse_if_read_only();
    if (edits.empty() && forget.empty() && !regions) return;
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      for (const SeqRange& r : forget) {
        for (const char* sql : {"DELETE FROM edit_log WHERE seq >= $1 AND seq <= $2",
                                "DELETE FROM rollbacks WHERE seq >= $1 AND seq <= $2"})
          t.exec_params(sql, static_cast<int64_t>(r.first), static_cast<int64_t>(r.last));
      }
      for (const LoggedEdit& e : edits) {
        const auto bytes = e.undoes ? encode_seq_list(*e.undoes) : encode_edit(e.edit, e.keep);
        t.exec_params(e.undoes ? "INSERT INTO rollbacks (seq, at_ms, author, undoes) VALUES "
                                 "($1, $2, $3, $4)"
                               : "INSERT INTO edit_log (seq, at_ms, author, edit) VALUES "
                                 "($1, $2, $3, $4)",
                      static_cast<int64_t>(e.seq), e.unix_ms, e.author, binary(bytes));
      }
      if (regions) write_regions(t, *regions);
      t.commit();
    });
  }

  void write_checkpoint(std::span<const ChunkRecord> chunks, uint64_t checkpoint_seq,
                        LogTrim trim) override {
    refuse_if_read_only();
    const auto seq = static_cast<int64_t>(checkpoint_seq);
    run([&](pqxx::connection& c) {
      for (size_t from = 0; from < chunks.size(); from += schema::kCheckpointPart) {
        pqxx::work t(c);
        // The parts need no flush of their own: the move below (or the next append) is
        // durable only after them, and losing them loses no edit (the log still has it).
        t.exec("SET LOCAL synchronous_commit = off");
        for (const ChunkRecord& r :
             chunks.subspan(from, std::min(schema::kCheckpointPart, chunks.size() - from))) {
          t.exec_params(
              "INSERT INTO chunks (x, y, z, seq, samples) VALUES ($1, $2, $3, $4, $5) "
              "ON CONFLICT (x, y, z, seq) DO UPDATE SET samples = excluded.samples",
              r.coord.x, r.coord.y, r.coord.z, seq, binary(r.samples));
        }
        t.commit();
      }
      pqxx::work t(c);  // the move: readers see the new rows from here on
      const auto rows = t.exec1(std::string(schema::kCountRowsOfSeq) + std::to_string(seq));
      if (rows[0].as<uint64_t>() != distinct_coords(chunks))
        throw StoreError(name_ + ": checkpoint " + std::to_string(checkpoint_seq) +
                         " lost rows while written (another writer?); not recorded");
      const uint64_t previous = info_from_meta(name_, read_meta(t)).checkpoint_seq;
      for (const ChunkRecord& r : chunks) {
        t.exec_params("DELETE FROM chunks WHERE x = $1 AND y = $2 AND z = $3 AND seq < $4",
                      r.coord.x, r.coord.y, r.coord.z, seq);
      }
      // Rows of checkpoints that failed after `previous` (their chunks are in this one).
      t.exec_params("DELETE FROM chunks WHERE seq > $1 AND seq < $2",
                    static_cast<int64_t>(previous), seq);
      t.exec_params(kUpsertMeta, schema::kMetaCheckpointSeq, std::to_string(checkpoint_seq));
      if (trim.through > 0)
        trim.windowed() ? t.exec_params(schema::kTrimLog, static_cast<int64_t>(trim.through),
                                        trim.accepted_before_ms, trim.stamps_until_ms)
                        : t.exec_params(schema::kTrimLogAll, static_cast<int64_t>(trim.through));
      if (trim.through > 0) {
        // The records before the first edit kept go with them, and the history's base.
        t.exec_params(
            "DELETE FROM rollbacks WHERE seq <= $1 AND seq < COALESCE((SELECT MIN(seq) FROM "
            "edit_log), CAST($1 AS BIGINT) + 1)",
            static_cast<int64_t>(trim.through));
        t.exec(schema::kDropBase);
      }
      t.commit();
    });
  }

  std::optional<ChunkRecord> read_chunk(world::ChunkCoord coord) override {
    std::optional<ChunkRecord> out;
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      const auto r = t.exec_params(
          "SELECT seq, samples FROM chunks WHERE x = $1 AND y = $2 AND z = $3 "
          "AND seq <= (SELECT CAST(value AS BIGINT) FROM meta WHERE key = "
          "'checkpoint_seq') ORDER BY seq DESC LIMIT 1",
          coord.x, coord.y, coord.z);
      if (r.empty()) return;
      const pqxx::binarystring samples(r[0][1]);
      out = ChunkRecord{
          coord, r[0][0].as<uint64_t>(), {samples.data(), samples.data() + samples.size()}};
    });
    return out;
  }

  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>& fn) override {
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      for (const auto& row : t.exec(schema::kVisibleChunkCoords))
        fn({row[0].as<int32_t>(), row[1].as<int32_t>(), row[2].as<int32_t>()},
           row[3].as<uint64_t>());
    });
  }

  RegionTable read_regions() override {
    std::vector<world::Region> out;
    uint64_t next = 1;
    run([&](pqxx::connection& c) {
      out.clear();
      pqxx::read_transaction t(c);
      if (t.exec1("SELECT to_regclass('regions') IS NULL")[0].as<bool>()) return;  // schema 2
      const Meta meta = read_meta(t);
      if (auto it = meta.find(schema::kMetaNextRegionId); it != meta.end())
        next = parse_meta_u64(name_, schema::kMetaNextRegionId, it->second);
      out = read_region_rows(t, "regions", name_);
    });
    return check_region_table(name_, std::move(out), next);
  }

  void for_each_edit(uint64_t after_seq,
                     const std::function<bool(const LoggedEdit&)>& fn) override {
    pages(after_seq, fn, [](pqxx::transaction_base& t, uint64_t from) {
      return t.exec_params(has_history(t) ? VOX_LOG_UNION " LIMIT 10000"
                                          : "SELECT seq, at_ms, author, edit, 0 FROM edit_log "
                                            "WHERE seq > $1 ORDER BY seq LIMIT 10000",
                           static_cast<int64_t>(from));
    });
  }

  void for_each_edit_back(uint64_t after_seq, uint64_t through_seq,
                          const std::function<bool(const LoggedEdit&)>& fn) override {
    const auto top = static_cast<int64_t>(std::min<uint64_t>(through_seq, INT64_MAX - 1));
    pages(top + 1, fn, [after_seq](pqxx::transaction_base& t, uint64_t below) {
      return t.exec_params(
          "SELECT seq, at_ms, author, edit, 0 FROM edit_log WHERE seq > $1 AND seq < $2 "
          "ORDER BY seq DESC LIMIT 10000",
          static_cast<int64_t>(after_seq), static_cast<int64_t>(below));
    });
  }

  void for_each_rollback(uint64_t after_seq,
                         const std::function<bool(const LoggedEdit&)>& fn) override {
    pages(after_seq, fn, [](pqxx::transaction_base& t, uint64_t from) {
      if (!has_history(t)) return pqxx::result{};
      return t.exec_params(
          "SELECT seq, at_ms, author, undoes, 1 FROM rollbacks WHERE seq > $1 ORDER BY seq "
          "LIMIT 10000",
          static_cast<int64_t>(from));
    });
  }

  std::optional<ChunkRecord> read_base_chunk(world::ChunkCoord coord) override {
    std::optional<ChunkRecord> out;
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      const WorldInfo i = info_from_meta(name_, read_meta(t));
      if (!i.base_seq) throw StoreError(name_ + ": no history is kept (no base)");
      const auto r =
          t.exec_params("SELECT samples FROM chunk_base WHERE x = $1 AND y = $2 AND z = $3",
                        coord.x, coord.y, coord.z);
      if (r.empty()) return;
      const pqxx::binarystring samples(r[0][0]);
      out = ChunkRecord{coord, *i.base_seq, {samples.data(), samples.data() + samples.size()}};
    });
    return out;
  }

  void advance_base(std::span<const ChunkRecord> chunks, uint64_t through) override {
    refuse_if_read_only();
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      const WorldInfo i = info_from_meta(name_, read_meta(t));
      if (!i.base_seq || through < *i.base_seq || through > i.checkpoint_seq)
        throw StoreError(name_ + ": the history cannot move to edit " + std::to_string(through));
      for (const ChunkRecord& r : chunks)
        t.exec_params(
            "INSERT INTO chunk_base (x, y, z, samples) VALUES ($1, $2, $3, $4) "
            "ON CONFLICT (x, y, z) DO UPDATE SET samples = excluded.samples",
            r.coord.x, r.coord.y, r.coord.z, binary(r.samples));
      trim_through(t, through);
      t.commit();
    });
  }

  void reset_base() override {
    refuse_if_read_only();
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      const WorldInfo i = info_from_meta(name_, read_meta(t));
      t.exec("DELETE FROM chunk_base");
      t.exec(
          "INSERT INTO chunk_base (x, y, z, samples) SELECT x, y, z, samples FROM chunks "
          "WHERE seq <= (SELECT CAST(value AS BIGINT) FROM meta WHERE key = 'checkpoint_seq')");
      trim_through(t, i.checkpoint_seq);
      t.commit();
    });
  }

 private:
  static bool has_history(pqxx::transaction_base& t) {
    return t.exec1("SELECT to_regclass('rollbacks') IS NOT NULL")[0].as<bool>();
  }

  // The log's edits through `through` go, with its records; the base is as of it.
  static void trim_through(pqxx::work& t, uint64_t through) {
    const auto seq = static_cast<int64_t>(through);
    t.exec_params("DELETE FROM edit_log WHERE seq <= $1", seq);
    t.exec_params("DELETE FROM rollbacks WHERE seq <= $1", seq);
    t.exec_params(kUpsertMeta, schema::kMetaBaseSeq, std::to_string(through));
  }

  // Rows of seq, at_ms, author, record, is_rollback, read in pages of 10,000 (a long log
  // is never one result in memory): `page(t, key)` reads those after (or, newest first,
  // before) the last key.
  template <class Page>
  void pages(uint64_t from, const std::function<bool(const LoggedEdit&)>& fn, Page page) {
    run([&](pqxx::connection& c) {
      pqxx::read_transaction t(c);
      uint64_t key = from;
      for (;;) {
        const pqxx::result rows = page(t, key);
        for (const auto& row : rows) {
          LoggedEdit e;
          e.seq = row[0].as<uint64_t>();
          e.unix_ms = row[1].as<int64_t>();
          e.author = row[2].as<std::string>();
          const pqxx::binarystring bytes(row[3]);
          row[4].as<int>() ? decode_logged_rollback(name_, {bytes.data(), bytes.size()}, e)
                           : decode_logged_edit(name_, {bytes.data(), bytes.size()}, e);
          if (!fn(e)) return;
          key = e.seq;
        }
        if (rows.size() < 10000) return;
      }
    });
  }

  // Inside an append's transaction: one statement per change; a repair, the whole table.
  static void write_regions(pqxx::work& t, const RegionWrite& w) {
    write_region_rows(t, "regions", w);
    t.exec_params(kUpsertMeta, schema::kMetaNextRegionId, std::to_string(w.next_id));
  }
  // Runs fn on the connection (opened, or reopened after a failure); every libpqxx
  // failure becomes a StoreError naming the store, and drops the connection.
  template <class Fn>
  void run(Fn&& fn) {
    run_on(
        conn_, name_,
        [&] {
          auto c = std::make_unique<pqxx::connection>(uri_);
          if (!options_.read_only && options_.record_start) lock_world(*c);
          return c;
        },
        fn);
  }

  // One writing process per world: a session advisory lock in this database, held by the
  // writer's first connection (PostgreSQL drops it when the connection goes, but only once
  // the backend has seen the close: a writer that has just stopped may still hold it for
  // a moment, so we wait up to kWriterLockWait for it).
  void lock_world(pqxx::connection& c) {
    pqxx::nontransaction t(c);
    const auto give_up = std::chrono::steady_clock::now() + kWriterLockWait;
    bool locked = false;
    while (!(locked = t.exec1("SELECT pg_try_advisory_lock(7008)")[0].as<bool>()) &&
           std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (!locked) {  // the new connection goes with the exception
      throw StoreError(name_ +
                       ": another voxeld is writing this world (it holds its lock); "
                       "stop it first");
    }
  }

  void refuse_if_read_only() const {
    if (options_.read_only) throw StoreError(name_ + ": opened read-only");
  }

  std::string uri_;
  std::string name_;
  OpenOptions options_;
  std::unique_ptr<pqxx::connection> conn_;
};

}  // namespace

std::string redact_uri(const std::string& uri) {
  std::string out = uri;
  // user:password@host
  const auto scheme = out.find("://");
  const auto at = out.find('@');
  if (scheme != std::string::npos && at != std::string::npos && at > scheme) {
    const auto colon = out.find(':', scheme + 3);
    if (colon != std::string::npos && colon < at)
      out = out.substr(0, colon) + ":***" + out.substr(at);
  }
  // ?password=… or &password=… in the query
  const auto query = out.find('?');
  for (auto p = query; p != std::string::npos && p < out.size(); p = out.find('&', p + 1)) {
    if (out.compare(p + 1, 9, "password=") != 0) continue;
    const auto value = p + 10;
    const auto end = std::min(out.find('&', value), out.size());
    out.replace(value, end - value, "***");
  }
  return out;
}

std::unique_ptr<WorldStore> open_postgres_store(const std::string& uri,
                                                const OpenOptions& options) {
  return std::make_unique<PostgresStore>(uri, options);
}

}  // namespace vox::store
