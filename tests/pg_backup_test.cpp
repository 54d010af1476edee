// A single node's PostgreSQL world backed up to a file (voxel-cli world backup
// postgresql://... --out FILE; server/store/pg_export.cpp) against a real PostgreSQL: more
// rows than one FETCH of each table, regions and bans; the file restores into a directory
// holding the same chunks, log, regions and bans. (SQLite worlds: WorldBackup.*.)
#include <gtest/gtest.h>

#include "server/store/ban_store.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/world_backup.hpp"
#include "server/store/world_store.hpp"
#include "tests/postgres_server.hpp"
#include "tests/store_test_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::store {
namespace {

using test::full_chunk;

TEST(PostgresBackup, APostgresqlWorldBacksUpToAFileThatRestoresRowForRow) {
  test::PostgresServer postgres;
  const std::string where = postgres.create_database("backup");
  {
    auto s = open_world_store(where, {.seed = 11});
    std::vector<LoggedEdit> log;
    for (uint64_t seq = 1; seq <= 700; ++seq)  // more than one FETCH of each
      log.push_back({seq, static_cast<int64_t>(seq), seq % 2 ? "alice" : "",
                     world::Paint{{1, 2, 3}, 2, static_cast<uint8_t>(1 + seq % 9)}});
    RegionWrite regions;
    world::Region r;
    r.id = 1, r.name = "spawn", r.flags = world::kRegionFlagsKnown, r.owners = {"alice"};
    r.box = {{0, 0, 0}, {8, 8, 8}};
    regions.upsert.push_back(r);
    regions.next_id = 2;
    s->append_edits(log, {}, &regions);
    std::vector<ChunkRecord> chunks;
    for (int x = 0; x < 300; ++x)
      chunks.push_back({{x, 0, 0}, 600, encode_chunk(full_chunk(static_cast<uint32_t>(x)))});
    s->write_checkpoint(chunks, 600, LogTrim{100});
    Ban b;
    b.target = "mallory", b.reason = "grief", b.created_ms = 5;
    open_ban_store(where)->put(b);
  }
  test::TempDir dir("pg_backup");
  const BackupFigures f = backup_postgres_world(where, (dir / "world.backup").string());
  EXPECT_GT(f.bytes, 0u);
  EXPECT_THROW(backup_postgres_world(where, (dir / "world.backup").string()), StoreError);
  EXPECT_EQ(restore_world((dir / "world.backup").string(), (dir / "restored").string(), false), "");
  auto from = open_world_store(where, {.read_only = true});
  auto to = open_world_store((dir / "restored").string(), {.read_only = true});
  const WorldInfo a = from->info(), b = to->info();
  EXPECT_EQ(b.seed, 11u);
  EXPECT_EQ(b.checkpoint_seq, a.checkpoint_seq);
  EXPECT_EQ(b.last_seq, 700u);
  EXPECT_EQ(b.logged_edits, 600u);  // 101..700
  EXPECT_EQ(b.modified_chunks, 300u);
  for (int x : {0, 150, 299})
    EXPECT_EQ(to->read_chunk({x, 0, 0})->samples, from->read_chunk({x, 0, 0})->samples);
  std::vector<std::pair<uint64_t, std::string>> la, lb;
  from->for_each_edit(0,
                      [&](const LoggedEdit& e) { return la.emplace_back(e.seq, e.author), true; });
  to->for_each_edit(0, [&](const LoggedEdit& e) { return lb.emplace_back(e.seq, e.author), true; });
  EXPECT_EQ(la, lb);
  const RegionTable regions = to->read_regions();
  ASSERT_EQ(regions.regions.size(), 1u);
  EXPECT_EQ(regions.regions[0].name, "spawn");
  EXPECT_EQ(regions.next_id, 2u);
  EXPECT_EQ(open_ban_store((dir / "restored").string())->read(0).bans.size(), 1u);
}

}  // namespace
}  // namespace vox::store
