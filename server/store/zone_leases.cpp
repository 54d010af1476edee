#include "server/store/zone_leases.hpp"

#include <algorithm>
#include <pqxx/pqxx>
#include <random>
#include <string>
#include <tuple>

#include "server/store/edit_codec.hpp"
#include "server/store/pq_errors.hpp"
#include "server/store/pq_regions.hpp"
#include "server/store/world_store_checks.hpp"
#include "server/store/zone_schema.hpp"

namespace vox::store {
namespace {

// Chunks written per transaction of a checkpoint.
constexpr size_t kChunksPerTransaction = 32;

// Rows key zones by ZoneId::key()'s bits as a signed BIGINT.
int64_t row_key(world::ZoneId z) { return static_cast<int64_t>(z.key()); }

// This process's mark on its node's heartbeat row: never 0 (the column's default).
int64_t random_instance() {
  std::random_device device;
  int64_t v = 0;
  while (v == 0) v = static_cast<int64_t>((uint64_t{device()} << 32) ^ device());
  return v;
}

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

}  // namespace

bool is_cluster_world(const std::string& uri) {
  return translate_pq_errors(
      "PostgreSQL " + redact_uri(uri), [] {},
      [&] {
        pqxx::connection c(uri);
        pqxx::read_transaction t(c);
        return t
            .exec1(
                "SELECT to_regclass('cluster_world') IS NOT NULL AND "
                "to_regclass('zones') IS NOT NULL")[0]
            .as<bool>();
      });
}

struct ZoneLeases::Connection {
  explicit Connection(const std::string& uri) : c(uri) {}
  pqxx::connection c;
};

template <typename Fn>
auto ZoneLeases::run(Fn&& fn) {
  return translate_pq_errors(
      name_, [&] { conn_.reset(); },
      [&] {
        if (!conn_ || !conn_->c.is_open()) {
          conn_ = std::make_unique<Connection>(with_connect_timeout(uri_, lease_));
          // A node stalled inside a transaction (SIGSTOP, a VM pause) holds its zone rows'
          // locks: the server ends its transaction after a lease, and nobody waits for a
          // lock longer than a quarter lease (the keeper's round must go on; it retries).
          const auto lease_ms = static_cast<long long>(lease_.count());
          pqxx::nontransaction n(conn_->c);
          n.exec("SET lock_timeout = " + std::to_string(std::max(lease_ms / 4, 50LL)) +
                 "; SET idle_in_transaction_session_timeout = " + std::to_string(lease_ms));
        }
        return fn(conn_->c);
      });
}

ZoneLeases::ZoneLeases(std::string uri, std::string node, std::chrono::milliseconds lease)
    : uri_(std::move(uri)),
      name_("PostgreSQL " + redact_uri(uri_)),
      node_(std::move(node)),
      lease_(lease),
      instance_(random_instance()) {
  if (node_.empty() || node_.size() > 200)
    throw StoreError(name_ + ": a node id must have 1 to 200 bytes");
  if (lease_ < std::chrono::milliseconds(100))
    throw StoreError(name_ + ": a lease must last at least 100 ms");
  run([](pqxx::connection& c) {
    pqxx::work t(c);
    // Altering a table locks it whole, even when there is nothing to alter: a connection
    // opened while others append (a follower starting) would wait behind their row locks,
    // and every reader behind it. So only a database without the whole schema is altered.
    if (t.exec1(kZoneTablesThere)[0].as<bool>()) return;
    t.exec("SELECT pg_advisory_xact_lock(7008)");         // one creator at a time
    if (t.exec1(kZoneTablesThere)[0].as<bool>()) return;  // the one before made it
    t.exec(kZoneTables);
    t.commit();
  });
}

ZoneLeases::~ZoneLeases() = default;

std::optional<uint64_t> ZoneLeases::acquire(world::ZoneId zone) {
  return run([&](pqxx::connection& c) -> std::optional<uint64_t> {
    pqxx::work t(c);
    t.exec_params(
        "INSERT INTO zones (zone, epoch, owner, lease_until) VALUES ($1, 0, NULL, now()) "
        "ON CONFLICT (zone) DO NOTHING",
        row_key(zone));
    const pqxx::row row = t.exec_params1(
        "SELECT epoch, owner IS NOT NULL AND owner <> $2 AND lease_until > now() "
        "FROM zones WHERE zone = $1 FOR UPDATE",
        row_key(zone), node_);
    if (row[1].as<bool>()) return std::nullopt;  // another node's lease runs
    // Taken anew even when the row names this node: a restarted process with the same id
    // must fence its earlier run, which may still be paused somewhere.
    const auto epoch = row[0].as<int64_t>() + 1;
    t.exec_params(
        "UPDATE zones SET epoch = $2, owner = $3, "
        "lease_until = now() + $4 * interval '1 millisecond' WHERE zone = $1",
        row_key(zone), epoch, node_, static_cast<int64_t>(lease_.count()));
    t.commit();
    return static_cast<uint64_t>(epoch);
  });
}

bool ZoneLeases::renew(world::ZoneId zone, uint64_t epoch) {
  return run([&](pqxx::connection& c) {
    pqxx::work t(c);
    const pqxx::result r = t.exec_params(
        "UPDATE zones SET lease_until = now() + $4 * interval '1 millisecond' "
        "WHERE zone = $1 AND epoch = $2 AND owner = $3",
        row_key(zone), static_cast<int64_t>(epoch), node_, static_cast<int64_t>(lease_.count()));
    t.commit();
    return r.affected_rows() == 1;
  });
}

void ZoneLeases::release(world::ZoneId zone, uint64_t epoch) {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params(
        "UPDATE zones SET owner = NULL, lease_until = now() "
        "WHERE zone = $1 AND epoch = $2 AND owner = $3",
        row_key(zone), static_cast<int64_t>(epoch), node_);
    t.commit();
  });
}

ZoneRegions ZoneLeases::read_regions() {
  return run([&](pqxx::connection& c) {
    pqxx::transaction<pqxx::repeatable_read, pqxx::read_only> t(c);  // the rows and version agree
    const pqxx::result r = t.exec("SELECT regions_version, next_region_id FROM cluster_world");
    ZoneRegions out;
    if (r.empty()) return out;
    out.version = r[0][0].as<uint64_t>();
    out.table = check_region_table(name_, read_region_rows(t, "zone_regions", name_),
                                   r[0][1].as<uint64_t>());
    return out;
  });
}

uint64_t ZoneLeases::regions_version() {
  return run([&](pqxx::connection& c) -> uint64_t {
    pqxx::read_transaction t(c);
    const pqxx::result r = t.exec("SELECT regions_version FROM cluster_world");
    return r.empty() ? 0 : r[0][0].as<uint64_t>();
  });
}

void ZoneLeases::seed_regions(const RegionTable& table) {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    const pqxx::result r = t.exec("SELECT regions_version FROM cluster_world FOR UPDATE");
    if (r.empty()) throw StoreError(name_ + ": the database holds no cluster world's settings");
    if (t.exec1("SELECT count(*) FROM zone_regions")[0].as<int64_t>() > 0)
      throw StoreError(name_ + ": the cluster world has protected regions already");
    write_region_rows(t, "zone_regions", {.whole = true, .upsert = table.regions});
    t.exec_params(
        "UPDATE cluster_world SET regions_version = regions_version + 1, "
        "next_region_id = GREATEST(next_region_id, $1)",
        static_cast<int64_t>(table.next_id));
    t.commit();
  });
}

void ZoneLeases::append(world::ZoneId zone, uint64_t epoch, std::span<const ZoneRecord> records) {
  const ZoneAppend one{zone, epoch, records};
  append(std::span<const ZoneAppend>(&one, 1));
}

uint64_t ZoneLeases::append(std::span<const ZoneAppend> appends, const RegionsAt* regions) {
  std::vector<const ZoneAppend*> order;
  for (const ZoneAppend& a : appends) {
    for (size_t i = 1; i < a.records.size(); ++i) {
      if (a.records[i].seq != a.records[i - 1].seq + 1)
        throw StoreError(name_ + ": " + describe(a.zone) + ": records " +
                         std::to_string(a.records[i - 1].seq) + " and " +
                         std::to_string(a.records[i].seq) + " leave a gap");
    }
    if (!a.records.empty()) order.push_back(&a);
  }
  const RegionWrite* region_write = regions ? regions->write : nullptr;
  if (order.empty() && !region_write) return regions ? regions->version : 0;
  // Rows locked in one order by every writer: two writers of overlapping zones never
  // wait for each other in a circle.
  std::sort(order.begin(), order.end(),
            [](const ZoneAppend* a, const ZoneAppend* b) { return a->zone < b->zone; });
  for (size_t i = 1; i < order.size(); ++i) {
    if (order[i]->zone == order[i - 1]->zone)
      throw StoreError(name_ + ": " + describe(order[i]->zone) + " twice in one append");
  }
  try {
    return run([&](pqxx::connection& c) -> uint64_t {
      pqxx::work t(c);
      // The regions first: a writer of them locks their row before any zone row, and the
      // others do not lock it (a change committed before this read is seen).
      uint64_t version = regions ? check_region_version(t, *regions, name_) : 0;
      for (const ZoneAppend* a : order) {
        // The fence: the zone row locked for the rest of the transaction, so no
        // successor's take can slip between this check and the commit.
        const pqxx::result r = t.exec_params(
            "SELECT epoch, last_seq FROM zones WHERE zone = $1 FOR UPDATE", row_key(a->zone));
        const uint64_t current = r.empty() ? 0 : r[0][0].as<uint64_t>();
        if (current != a->epoch) {
          throw FencedError(name_ + ": " + describe(a->zone) + " is at epoch " +
                                std::to_string(current) + ", this write's is " +
                                std::to_string(a->epoch) + ": another node took it; write refused",
                            a->zone);
        }
        const auto last = r[0][1].as<uint64_t>();
        if (a->records.front().seq != last + 1)
          throw StoreError(name_ + ": " + describe(a->zone) + " ends at record " +
                           std::to_string(last) + "; an append starting at " +
                           std::to_string(a->records.front().seq) + " refused");
        for (const ZoneRecord& rec : a->records) {
          t.exec_params(
              "INSERT INTO zone_log (zone, seq, epoch, at_ms, record, edit_id) "
              "VALUES ($1, $2, $3, $4, $5, $6)",
              row_key(a->zone), static_cast<int64_t>(rec.seq), static_cast<int64_t>(a->epoch),
              rec.unix_ms, pqxx::binarystring(rec.payload.data(), rec.payload.size()),
              static_cast<int64_t>(rec.edit_id));
        }
        t.exec_params("UPDATE zones SET last_seq = $2 WHERE zone = $1", row_key(a->zone),
                      static_cast<int64_t>(a->records.back().seq));
      }
      // Pending parts: each zone's own part that landed removes its row (nothing is left
      // to complete); the other zones' parts are written unless their logs have them
      // already (a concurrent writer's part not yet visible leaves a stale row:
      // read_pending drops it). All in one order, by (zone, edit id), for every writer:
      // writers touching the same pending keys (which wait for each other) never wait in
      // a circle.
      struct PendingOp {
        int64_t zone;
        uint64_t edit_id;
        const ZonePending* insert;  // null: the zone's own part landed
      };
      std::vector<PendingOp> ops;
      for (const ZoneAppend* a : order) {
        for (const ZoneRecord& rec : a->records) {
          if (rec.edit_id != 0) ops.push_back({row_key(a->zone), rec.edit_id, nullptr});
        }
        for (const ZonePending& p : a->pending) ops.push_back({row_key(p.zone), p.edit_id, &p});
      }
      std::sort(ops.begin(), ops.end(), [](const PendingOp& x, const PendingOp& y) {
        return std::tuple(x.zone, x.edit_id, x.insert != nullptr) <
               std::tuple(y.zone, y.edit_id, y.insert != nullptr);
      });
      for (const PendingOp& op : ops) {
        if (!op.insert) {
          t.exec_params("DELETE FROM zone_pending WHERE zone = $1 AND edit_id = $2", op.zone,
                        static_cast<int64_t>(op.edit_id));
          continue;
        }
        const ZonePending& p = *op.insert;
        t.exec_params(
            "INSERT INTO zone_pending (zone, edit_id, at_ms, record) "
            "SELECT $1, $2, $3, $4 WHERE NOT EXISTS "
            "(SELECT 1 FROM zone_log WHERE zone = $1 AND edit_id = $2 AND edit_id <> 0) "
            "ON CONFLICT (zone, edit_id) DO NOTHING",
            op.zone, static_cast<int64_t>(p.edit_id), p.unix_ms,
            pqxx::binarystring(p.payload.data(), p.payload.size()));
      }
      if (region_write) {
        write_region_rows(t, "zone_regions", *region_write);
        t.exec_params(
            "UPDATE cluster_world SET regions_version = $1, "
            "next_region_id = GREATEST(next_region_id, $2)",
            static_cast<int64_t>(++version), static_cast<int64_t>(region_write->next_id));
      }
      t.commit();
      return version;
    });
  } catch (const RegionsChangedError&) {
    throw;  // no zone was fenced
  } catch (const FencedError&) {
    ++fenced_;
    throw;
  }
}

std::vector<ZonePending> ZoneLeases::read_pending(std::span<const world::ZoneId> zones,
                                                  std::chrono::milliseconds age, size_t max) {
  if (zones.empty()) return {};
  std::string keys = "{";
  for (size_t i = 0; i < zones.size(); ++i) {
    if (i > 0) keys += ',';
    keys += std::to_string(row_key(zones[i]));
  }
  keys += "}";
  return run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params(
        "DELETE FROM zone_pending p WHERE p.zone = ANY($1::BIGINT[]) AND EXISTS "
        "(SELECT 1 FROM zone_log l WHERE l.zone = p.zone AND l.edit_id = p.edit_id "
        "AND l.edit_id <> 0)",
        keys);
    std::vector<ZonePending> out;
    for (const auto& row : t.exec_params(
             "SELECT zone, edit_id, at_ms, record FROM zone_pending WHERE zone = ANY($1::BIGINT[]) "
             "AND since <= now() - $2 * interval '1 millisecond' ORDER BY since, edit_id LIMIT $3",
             keys, static_cast<int64_t>(age.count()), static_cast<int64_t>(max))) {
      const pqxx::binarystring bytes(row[3]);
      out.push_back({world::ZoneId::from_key(static_cast<uint64_t>(row[0].as<int64_t>())),
                     static_cast<uint64_t>(row[1].as<int64_t>()), row[2].as<int64_t>(),
                     std::vector<uint8_t>(bytes.begin(), bytes.end())});
    }
    t.commit();
    return out;
  });
}

void ZoneLeases::drop_pending(world::ZoneId zone, uint64_t edit_id) {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params("DELETE FROM zone_pending WHERE zone = $1 AND edit_id = $2", row_key(zone),
                  static_cast<int64_t>(edit_id));
    t.commit();
  });
}

std::vector<ZoneRecord> ZoneLeases::read_log(world::ZoneId zone, uint64_t after_seq, size_t max) {
  return run([&](pqxx::connection& c) {
    pqxx::read_transaction t(c);
    std::vector<ZoneRecord> out;
    for (const auto& row : t.exec_params(
             "SELECT seq, at_ms, record, edit_id FROM zone_log WHERE zone = $1 AND seq > $2 "
             "ORDER BY seq LIMIT $3",
             row_key(zone), static_cast<int64_t>(after_seq), static_cast<int64_t>(max))) {
      const pqxx::binarystring bytes(row[2]);
      out.push_back({row[0].as<uint64_t>(), row[1].as<int64_t>(),
                     std::vector<uint8_t>(bytes.begin(), bytes.end()),
                     static_cast<uint64_t>(row[3].as<int64_t>())});
    }
    return out;
  });
}

std::optional<ZoneRow> ZoneLeases::read(world::ZoneId zone) {
  return run([&](pqxx::connection& c) -> std::optional<ZoneRow> {
    pqxx::read_transaction t(c);
    const pqxx::result r = t.exec_params(
        "SELECT epoch, COALESCE(owner, ''), "
        "CAST(EXTRACT(EPOCH FROM (lease_until - now())) * 1000 AS BIGINT), last_seq, "
        "checkpoint_seq FROM zones WHERE zone = $1",
        row_key(zone));
    if (r.empty()) return std::nullopt;
    return ZoneRow{r[0][0].as<uint64_t>(), r[0][1].as<std::string>(), r[0][2].as<int64_t>(),
                   r[0][3].as<uint64_t>(), r[0][4].as<uint64_t>()};
  });
}

void ZoneLeases::write_checkpoint(uint64_t epoch, const ZoneCheckpoint& cp) {
  const int64_t zone = row_key(cp.zone);
  const auto fenced = [&](uint64_t current) {
    ++fenced_;
    return FencedError(name_ + ": " + describe(cp.zone) + " is at epoch " +
                           std::to_string(current) + ", this checkpoint's is " +
                           std::to_string(epoch) + ": another node took it; write refused",
                       cp.zone);
  };
  for (const ChunkRecord& c : cp.chunks) {
    if (c.seq > cp.seq || c.seq == 0)
      throw StoreError(name_ + ": " + describe(cp.zone) + ": a chunk at record " +
                       std::to_string(c.seq) + " in a checkpoint through record " +
                       std::to_string(cp.seq));
  }
  // Not worth writing for a zone already taken (the fence below decides, though), nor when
  // one as new is there (a retry).
  const std::optional<ZoneRow> row = read(cp.zone);
  if (!row || row->epoch != epoch) throw fenced(row ? row->epoch : 0);
  if (cp.seq <= row->checkpoint_seq) return;
  for (size_t first = 0; first < cp.chunks.size(); first += kChunksPerTransaction) {
    const size_t last = std::min(cp.chunks.size(), first + kChunksPerTransaction);
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
      for (size_t i = first; i < last; ++i) {
        const ChunkRecord& r = cp.chunks[i];
        // The same version written again (a retry) holds the same samples: the log's.
        t.exec_params(
            "INSERT INTO zone_chunks (zone, cx, cy, cz, seq, epoch, samples) "
            "VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT DO NOTHING",
            zone, r.coord.x, r.coord.y, r.coord.z, static_cast<int64_t>(r.seq),
            static_cast<int64_t>(epoch), pqxx::binarystring(r.samples.data(), r.samples.size()));
      }
      t.commit();
    });
  }
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    const pqxx::result r = t.exec_params(
        "SELECT epoch, last_seq, checkpoint_seq FROM zones WHERE zone = $1 FOR UPDATE", zone);
    const uint64_t current = r.empty() ? 0 : r[0][0].as<uint64_t>();
    if (current != epoch) throw fenced(current);
    if (cp.seq > r[0][1].as<uint64_t>())
      throw StoreError(name_ + ": " + describe(cp.zone) + " ends at record " +
                       r[0][1].as<std::string>() + "; a checkpoint through record " +
                       std::to_string(cp.seq) + " refused");
    if (cp.seq <= r[0][2].as<uint64_t>()) return;  // one as new is there (a retry)
    t.exec_params("UPDATE zones SET checkpoint_seq = $2 WHERE zone = $1", zone,
                  static_cast<int64_t>(cp.seq));
    // The versions this checkpoint's replace: no reader needs them any more.
    t.exec_params(
        "DELETE FROM zone_chunks o USING zone_chunks n WHERE n.zone = $1 AND n.seq = $2 "
        "AND o.zone = $1 AND o.cx = n.cx AND o.cy = n.cy AND o.cz = n.cz AND o.seq < n.seq",
        zone, static_cast<int64_t>(cp.seq));
    t.commit();
  });
}

std::optional<ZoneCheckpoint> ZoneLeases::read_checkpoint(world::ZoneId zone, size_t max_edit_ids) {
  return run([&](pqxx::connection& c) -> std::optional<ZoneCheckpoint> {
    pqxx::transaction<pqxx::repeatable_read, pqxx::read_only> t(c);
    const pqxx::result r =
        t.exec_params("SELECT checkpoint_seq FROM zones WHERE zone = $1", row_key(zone));
    if (r.empty() || r[0][0].as<uint64_t>() == 0) return std::nullopt;
    ZoneCheckpoint out{.zone = zone, .seq = r[0][0].as<uint64_t>(), .chunks = {}, .edit_ids = {}};
    const auto seq = static_cast<int64_t>(out.seq);
    for (const auto& row :
         t.exec_params("SELECT DISTINCT ON (cx, cy, cz) cx, cy, cz, seq, samples FROM zone_chunks "
                       "WHERE zone = $1 AND seq <= $2 ORDER BY cx, cy, cz, seq DESC",
                       row_key(zone), seq)) {
      const pqxx::binarystring bytes(row[4]);
      out.chunks.push_back({{row[0].as<int32_t>(), row[1].as<int32_t>(), row[2].as<int32_t>()},
                            row[3].as<uint64_t>(),
                            std::vector<uint8_t>(bytes.begin(), bytes.end())});
    }
    for (const auto& row : t.exec_params(
             "SELECT edit_id FROM (SELECT seq, edit_id FROM zone_log WHERE zone = $1 "
             "AND seq <= $2 AND edit_id <> 0 ORDER BY seq DESC LIMIT $3) AS l ORDER BY seq",
             row_key(zone), seq, static_cast<int64_t>(max_edit_ids)))
      out.edit_ids.push_back(static_cast<uint64_t>(row[0].as<int64_t>()));
    return out;
  });
}

std::optional<ChunkRecord> ZoneLeases::read_chunk(world::ZoneId zone, world::ChunkCoord chunk,
                                                  uint64_t applied) {
  return run([&](pqxx::connection& c) -> std::optional<ChunkRecord> {
    pqxx::read_transaction t(c);
    const pqxx::result r = t.exec_params(
        "SELECT z.checkpoint_seq, v.seq, v.samples FROM zones z LEFT JOIN LATERAL "
        "(SELECT seq, samples FROM zone_chunks WHERE zone = z.zone AND cx = $2 AND cy = $3 "
        "AND cz = $4 AND seq <= z.checkpoint_seq ORDER BY seq DESC LIMIT 1) v ON TRUE "
        "WHERE z.zone = $1",
        row_key(zone), chunk.x, chunk.y, chunk.z);
    if (r.empty()) return std::nullopt;
    const auto checkpoint = r[0][0].as<uint64_t>();
    if (checkpoint > applied)
      throw StoreError(name_ + ": " + describe(zone) + ": its checkpoint (record " +
                       std::to_string(checkpoint) + ") is past what this world applied (" +
                       std::to_string(applied) + "); chunk (" + std::to_string(chunk.x) + ", " +
                       std::to_string(chunk.y) + ", " + std::to_string(chunk.z) +
                       ") is read again once the zone is installed afresh");
    if (r[0][1].is_null()) return std::nullopt;
    const pqxx::binarystring bytes(r[0][2]);
    return ChunkRecord{chunk, r[0][1].as<uint64_t>(),
                       std::vector<uint8_t>(bytes.begin(), bytes.end())};
  });
}

std::optional<WorldSettings> ZoneLeases::world_settings() {
  return run([&](pqxx::connection& c) -> std::optional<WorldSettings> {
    pqxx::read_transaction t(c);
    const pqxx::result r = t.exec("SELECT name, seed, zone_chunks FROM cluster_world");
    if (r.empty()) return std::nullopt;
    return WorldSettings{r[0][0].as<std::string>(), static_cast<uint64_t>(r[0][1].as<int64_t>()),
                         r[0][2].as<int>()};
  });
}

std::vector<world::ZoneId> ZoneLeases::zones() {
  return run([&](pqxx::connection& c) {
    pqxx::read_transaction t(c);
    std::vector<world::ZoneId> out;
    for (const auto& row : t.exec("SELECT zone FROM zones ORDER BY zone"))
      out.push_back(world::ZoneId::from_key(static_cast<uint64_t>(row[0].as<int64_t>())));
    return out;
  });
}

void ZoneLeases::seed_zones(std::span<const ZoneSeed> zones) {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    for (const ZoneSeed& seed : zones) {
      const int64_t zone = row_key(seed.zone);
      const pqxx::result r = t.exec_params(
          "SELECT epoch, last_seq, checkpoint_seq FROM zones WHERE zone = $1 FOR UPDATE", zone);
      if (r.empty() || r[0][0].as<uint64_t>() != seed.epoch)
        throw StoreError(name_ + ": " + describe(seed.zone) + " is not held at epoch " +
                         std::to_string(seed.epoch));
      if (r[0][1].as<uint64_t>() != 0 || r[0][2].as<uint64_t>() != 0)
        throw StoreError(name_ + ": " + describe(seed.zone) + " has records already");
      for (const ChunkRecord& ch : seed.chunks) {
        t.exec_params(
            "INSERT INTO zone_chunks (zone, cx, cy, cz, seq, epoch, samples) "
            "VALUES ($1, $2, $3, $4, 1, $5, $6)",
            zone, ch.coord.x, ch.coord.y, ch.coord.z, static_cast<int64_t>(seed.epoch),
            pqxx::binarystring(ch.samples.data(), ch.samples.size()));
      }
      t.exec_params("UPDATE zones SET last_seq = 1, checkpoint_seq = 1 WHERE zone = $1", zone);
    }
    t.commit();
  });
}

std::optional<std::string> ZoneLeases::heartbeat(const std::string& address) {
  return run([&](pqxx::connection& c) -> std::optional<std::string> {
    pqxx::work t(c);
    // The row is this process's, or free again once its last heartbeat ran out.
    const pqxx::result r = t.exec_params(
        "INSERT INTO nodes (node, address, alive_until, instance) "
        "VALUES ($1, $2, now() + $3 * interval '1 millisecond', $4) ON CONFLICT (node) DO UPDATE "
        "SET address = excluded.address, alive_until = excluded.alive_until, "
        "instance = excluded.instance "
        "WHERE nodes.instance = excluded.instance OR nodes.alive_until <= now()",
        node_, address, static_cast<int64_t>(lease_.count()), instance_);
    if (r.affected_rows() == 1) {
      t.commit();
      return std::nullopt;
    }
    return t.exec_params1("SELECT address FROM nodes WHERE node = $1", node_)[0].as<std::string>();
  });
}

void ZoneLeases::leave() {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params("DELETE FROM nodes WHERE node = $1 AND instance = $2", node_, instance_);
    t.commit();
  });
}

std::vector<std::string> ZoneLeases::live_nodes() {
  return run([&](pqxx::connection& c) {
    pqxx::read_transaction t(c);
    std::vector<std::string> out;
    for (const auto& row : t.exec("SELECT node FROM nodes WHERE alive_until > now() ORDER BY node"))
      out.push_back(row[0].as<std::string>());
    return out;
  });
}

WorldSettings ZoneLeases::settle_world(const WorldSettings& mine) {
  return run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params(
        "INSERT INTO cluster_world (name, seed, zone_chunks) VALUES ($1, $2, $3) "
        "ON CONFLICT DO NOTHING",
        mine.name, static_cast<int64_t>(mine.seed), mine.zone_chunks);
    const pqxx::row r = t.exec1("SELECT name, seed, zone_chunks FROM cluster_world");
    t.commit();
    return WorldSettings{r[0].as<std::string>(), static_cast<uint64_t>(r[1].as<int64_t>()),
                         r[2].as<int>()};
  });
}

}  // namespace vox::store
