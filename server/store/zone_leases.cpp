#include "server/store/zone_leases.hpp"

#include <algorithm>
#include <pqxx/pqxx>
#include <string>
#include <tuple>

#include "server/store/pq_errors.hpp"

namespace vox::store {
namespace {

constexpr const char* kCreateTables = R"sql(
CREATE TABLE IF NOT EXISTS zones (zone BIGINT PRIMARY KEY, epoch BIGINT NOT NULL,
                                  owner TEXT, lease_until TIMESTAMPTZ NOT NULL,
                                  last_seq BIGINT NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS zone_log (zone BIGINT NOT NULL, seq BIGINT NOT NULL,
                                     epoch BIGINT NOT NULL, at_ms BIGINT NOT NULL,
                                     record BYTEA NOT NULL, PRIMARY KEY (zone, seq));
CREATE TABLE IF NOT EXISTS nodes (node TEXT PRIMARY KEY, address TEXT NOT NULL,
                                  alive_until TIMESTAMPTZ NOT NULL);
CREATE TABLE IF NOT EXISTS cluster_world (one BOOLEAN PRIMARY KEY DEFAULT TRUE CHECK (one),
                                          name TEXT NOT NULL, seed BIGINT NOT NULL,
                                          zone_chunks INTEGER NOT NULL);
ALTER TABLE zone_log ADD COLUMN IF NOT EXISTS edit_id BIGINT NOT NULL DEFAULT 0;
CREATE INDEX IF NOT EXISTS zone_log_edit ON zone_log (zone, edit_id) WHERE edit_id <> 0;
CREATE TABLE IF NOT EXISTS zone_pending (zone BIGINT NOT NULL, edit_id BIGINT NOT NULL,
                                         at_ms BIGINT NOT NULL, record BYTEA NOT NULL,
                                         since TIMESTAMPTZ NOT NULL DEFAULT now(),
                                         PRIMARY KEY (zone, edit_id));
)sql";

// Rows key zones by ZoneId::key()'s bits as a signed BIGINT.
int64_t row_key(world::ZoneId z) { return static_cast<int64_t>(z.key()); }

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

}  // namespace

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
          conn_ = std::make_unique<Connection>(uri_);
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
      lease_(lease) {
  if (node_.empty() || node_.size() > 200)
    throw StoreError(name_ + ": a node id must have 1 to 200 bytes");
  if (lease_ < std::chrono::milliseconds(100))
    throw StoreError(name_ + ": a lease must last at least 100 ms");
  run([](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec("SELECT pg_advisory_xact_lock(7008)");  // one creator at a time
    t.exec(kCreateTables);
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

void ZoneLeases::append(world::ZoneId zone, uint64_t epoch, std::span<const ZoneRecord> records) {
  const ZoneAppend one{zone, epoch, records};
  append(std::span<const ZoneAppend>(&one, 1));
}

void ZoneLeases::append(std::span<const ZoneAppend> appends) {
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
  if (order.empty()) return;
  // Rows locked in one order by every writer: two writers of overlapping zones never
  // wait for each other in a circle.
  std::sort(order.begin(), order.end(),
            [](const ZoneAppend* a, const ZoneAppend* b) { return a->zone < b->zone; });
  for (size_t i = 1; i < order.size(); ++i) {
    if (order[i]->zone == order[i - 1]->zone)
      throw StoreError(name_ + ": " + describe(order[i]->zone) + " twice in one append");
  }
  try {
    run([&](pqxx::connection& c) {
      pqxx::work t(c);
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
      t.commit();
    });
  } catch (const FencedError&) {
    ++fenced_;
    throw;
  }
}

std::vector<ZonePending> ZoneLeases::read_pending(std::span<const world::ZoneId> zones,
                                                  std::chrono::milliseconds age, size_t max) {
  if (zones.empty()) return {};
  std::string keys = "{";
  for (size_t i = 0; i < zones.size(); ++i)
    keys += (i ? "," : "") + std::to_string(row_key(zones[i]));
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
        "CAST(EXTRACT(EPOCH FROM (lease_until - now())) * 1000 AS BIGINT), last_seq "
        "FROM zones WHERE zone = $1",
        row_key(zone));
    if (r.empty()) return std::nullopt;
    return ZoneRow{r[0][0].as<uint64_t>(), r[0][1].as<std::string>(), r[0][2].as<int64_t>(),
                   r[0][3].as<uint64_t>()};
  });
}

void ZoneLeases::heartbeat(const std::string& address) {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params(
        "INSERT INTO nodes (node, address, alive_until) "
        "VALUES ($1, $2, now() + $3 * interval '1 millisecond') ON CONFLICT (node) DO UPDATE "
        "SET address = excluded.address, alive_until = excluded.alive_until",
        node_, address, static_cast<int64_t>(lease_.count()));
    t.commit();
  });
}

void ZoneLeases::leave() {
  run([&](pqxx::connection& c) {
    pqxx::work t(c);
    t.exec_params("DELETE FROM nodes WHERE node = $1", node_);
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
