// The schema of a cluster world in PostgreSQL (docs/CLUSTER.md): zones with their epochs
// and leases, their logs, parts pending, nodes' heartbeats, the world's settings and the
// zones' chunk versions and the protected regions. Created by ZoneLeases on its first
// connection.
#pragma once

#include "server/store/store_schema.hpp"

namespace vox::store {

// Each column and index is added only when missing: an ALTER with nothing to do would
// still lock a busy table whole (a rolling upgrade of live nodes).
inline constexpr const char* kZoneTables =
    R"sql(
CREATE OR REPLACE FUNCTION pg_temp.vox_add_column(t TEXT, c TEXT, decl TEXT) RETURNS void
LANGUAGE plpgsql AS $$ BEGIN
  IF NOT EXISTS (SELECT 1 FROM information_schema.columns WHERE table_schema = current_schema()
                 AND table_name = t AND column_name = c) THEN
    EXECUTE format('ALTER TABLE %I ADD COLUMN %I %s', t, c, decl);
  END IF;
END $$;
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
SELECT pg_temp.vox_add_column('zone_log', 'edit_id', 'BIGINT NOT NULL DEFAULT 0');
DO $$ BEGIN
  IF to_regclass('zone_log_edit') IS NULL THEN
    CREATE INDEX zone_log_edit ON zone_log (zone, edit_id) WHERE edit_id <> 0;
  END IF;
END $$;
CREATE TABLE IF NOT EXISTS zone_pending (zone BIGINT NOT NULL, edit_id BIGINT NOT NULL,
                                         at_ms BIGINT NOT NULL, record BYTEA NOT NULL,
                                         since TIMESTAMPTZ NOT NULL DEFAULT now(),
                                         PRIMARY KEY (zone, edit_id));
SELECT pg_temp.vox_add_column('zones', 'checkpoint_seq', 'BIGINT NOT NULL DEFAULT 0');
CREATE TABLE IF NOT EXISTS zone_chunks (zone BIGINT NOT NULL, cx INTEGER NOT NULL,
                                        cy INTEGER NOT NULL, cz INTEGER NOT NULL,
                                        seq BIGINT NOT NULL, epoch BIGINT NOT NULL,
                                        samples BYTEA NOT NULL,
                                        PRIMARY KEY (zone, cx, cy, cz, seq));
SELECT pg_temp.vox_add_column('nodes', 'instance', 'BIGINT NOT NULL DEFAULT 0');
SELECT pg_temp.vox_add_column('cluster_world', 'regions_version', 'BIGINT NOT NULL DEFAULT 0');
SELECT pg_temp.vox_add_column('cluster_world', 'next_region_id', 'BIGINT NOT NULL DEFAULT 1');
)sql"
    // The protected regions (docs/CLUSTER.md, "Protected regions"), as a single node keeps
    // them; cluster_world's regions_version counts their changes.
    "CREATE TABLE IF NOT EXISTS zone_regions " VOX_REGION_TABLE ";";

// Whether kZoneTables has nothing left to do (its last table and columns are there).
inline constexpr const char* kZoneTablesThere = R"sql(
SELECT to_regclass('zone_chunks') IS NOT NULL AND to_regclass('zone_log_edit') IS NOT NULL
       AND to_regclass('zone_pending') IS NOT NULL AND to_regclass('cluster_world') IS NOT NULL
       AND to_regclass('nodes') IS NOT NULL AND to_regclass('zone_regions') IS NOT NULL
       AND (SELECT count(*) FROM information_schema.columns WHERE table_schema = current_schema()
            AND ((table_name = 'zones' AND column_name = 'checkpoint_seq')
                 OR (table_name = 'zone_log' AND column_name = 'edit_id')
                 OR (table_name = 'nodes' AND column_name = 'instance')
                 OR (table_name = 'cluster_world' AND column_name IN ('regions_version',
                                                                      'next_region_id')))) = 5
)sql";

}  // namespace vox::store
