// The world store's backends, against real databases: SQLite in a temporary world
// directory and a real PostgreSQL server (tests/postgres_server.hpp). The same suite runs
// on both; SQLite's file cases (corrupt, truncated, newer schema) follow.
#include "server/store/world_store.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <thread>

#include "server/store/chunk_codec.hpp"
#include "server/store/edit_codec.hpp"
#include "server/store/postgres_store.hpp"
#include "server/store/sqlite_store.hpp"
#include "tests/postgres_server.hpp"
#include "tests/store_test_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::store {
namespace {

using test::full_chunk;

namespace fs = std::filesystem;

// Bit-for-bit equality of two edits (encodings compare every float exactly).
bool same(const world::Edit& a, const world::Edit& b) { return encode_edit(a) == encode_edit(b); }

// A schema-1 world holding chunk (1, 2, 3) at seq 3 (checkpoint 3, seed 5): readers read it
// as it is (a world from before regions has none); a writer migrates it, reads it, and
// checkpoints over it.
void expect_schema_one_world_migrates(const std::string& where) {
  {
    auto reader = open_world_store(where, {.read_only = true});
    EXPECT_TRUE(reader->read_chunk({1, 2, 3}));
    EXPECT_EQ(reader->info().checkpoint_seq, 3u);
    EXPECT_TRUE(reader->read_regions().regions.empty());
  }
  auto s = open_world_store(where, {.seed = 5});
  EXPECT_TRUE(s->read_regions().regions.empty());
  const auto r = s->read_chunk({1, 2, 3});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->seq, 3u);
  const world::Chunk a = full_chunk(1);
  s->write_checkpoint(std::vector<ChunkRecord>{{{1, 2, 3}, 8, encode_chunk(a)}}, 8, 8);
  EXPECT_TRUE(*decode_chunk(s->read_chunk({1, 2, 3})->samples) == a);
  EXPECT_EQ(s->info().modified_chunks, 1u);
}

// One backend: SQLite in a fresh directory, or a fresh database on the shared server.
class WorldStoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {}
  static void TearDownTestSuite() { postgres_.reset(); }

  // Where a fresh world lives for this backend (SQLite: a directory not made yet).
  std::string fresh_world() {
    static int n = 0;
    if (GetParam() == "sqlite") return (tmp_.emplace("store") / "world").string();
    if (!postgres_) postgres_ = std::make_unique<test::PostgresServer>();
    return postgres_->create_database("world" + std::to_string(n++));
  }
  static std::unique_ptr<test::PostgresServer> postgres_;
  std::optional<test::TempDir> tmp_;  // SQLite's world, removed after the test
};
std::unique_ptr<test::PostgresServer> WorldStoreTest::postgres_;

TEST_P(WorldStoreTest, ANewWorldRecordsItsSeedAndCountsItsStarts) {
  const std::string where = fresh_world();
  {
    auto s = open_world_store(where, {.seed = 42});
    const WorldInfo i = s->info();
    EXPECT_EQ(i.seed, 42u);
    EXPECT_EQ(i.starts, 1u);
    EXPECT_EQ(i.last_seq, 0u);
    EXPECT_EQ(i.modified_chunks, 0u);
  }
  auto again = open_world_store(where, {.seed = 42});
  EXPECT_EQ(again->info().starts, 2u);
}

TEST_P(WorldStoreTest, AnotherSeedIsRefusedNamingBoth) {
  const std::string where = fresh_world();
  open_world_store(where, {.seed = 7});
  try {
    open_world_store(where, {.seed = 8});
    FAIL() << "opened a seed-7 world with seed 8";
  } catch (const StoreError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("seed 7"), std::string::npos) << m;
    EXPECT_NE(m.find("not 8"), std::string::npos) << m;
  }
  EXPECT_EQ(open_world_store(where, {})->info().seed, 7u);  // and nothing was changed
}

TEST_P(WorldStoreTest, AppendedEditsComeBackInOrderBitForBit) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  const auto edits = test::one_edit_of_each_kind();
  std::vector<LoggedEdit> batch;
  for (size_t i = 0; i < edits.size(); ++i)
    batch.push_back(
        {i + 1, 1700000000000 + static_cast<int64_t>(i), i % 2 ? "alice" : "", edits[i]});
  s->append_edits({batch.data(), 3});
  s->append_edits({batch.data() + 3, batch.size() - 3});
  std::vector<LoggedEdit> back;
  s->for_each_edit(0, [&](const LoggedEdit& e) {
    back.push_back(e);
    return true;
  });
  ASSERT_EQ(back.size(), batch.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back[i].seq, batch[i].seq);
    EXPECT_EQ(back[i].unix_ms, batch[i].unix_ms);
    EXPECT_EQ(back[i].author, batch[i].author);
    EXPECT_TRUE(same(back[i].edit, batch[i].edit)) << describe_edit(back[i].edit);
  }
  size_t after_five = 0;
  s->for_each_edit(5, [&](const LoggedEdit& e) {
    EXPECT_GT(e.seq, 5u);
    ++after_five;
    return true;
  });
  EXPECT_EQ(after_five, batch.size() - 5);
  EXPECT_EQ(s->info().last_seq, batch.size());
  EXPECT_EQ(s->info().logged_edits, batch.size());
}

// Protected regions are written with an append (in its transaction), as changes or a
// whole table, and read back as they were with the next id; a clipped edit's boxes come
// back with it.
TEST_P(WorldStoreTest, RegionsAreWrittenWithAnAppendAndReadBack) {
  const std::string where = fresh_world();
  auto s = open_world_store(where, {.seed = 1});
  EXPECT_TRUE(s->read_regions().regions.empty());
  EXPECT_EQ(s->read_regions().next_id, 1u);
  world::Region a{.id = 3,
                  .name = "spawn",
                  .box = {{-10, -5, -10}, {10, 20, 10}},
                  .flags = world::kProtectBuild | world::kProtectExplode,
                  .owners = {"alice", "bob"},
                  .created_by = "admin-1",
                  .created_unix_ms = 1700000000123};
  world::Region b{.id = 9, .box = {{100, 0, 100}, {131, 31, 131}}, .flags = world::kProtectExplode};
  const std::vector<world::VoxelBox> keep{{{-10, -5, -10}, {-8, 0, -9}}};
  const RegionWrite both{.upsert = {a, b}, .next_id = 10};
  s->append_edits(
      std::vector<LoggedEdit>{{1, 0, "mallory", world::Explosion{{-12, 0, -12}, 4, 1}, keep}}, {},
      &both);
  const RegionTable table = s->read_regions();
  EXPECT_EQ(table.next_id, 10u);
  const auto& back = table.regions;
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].name, "spawn");
  EXPECT_EQ(back[0].box.lo, a.box.lo);
  EXPECT_EQ(back[0].box.hi, a.box.hi);
  EXPECT_EQ(back[0].owners, a.owners);
  EXPECT_EQ(back[0].created_by, "admin-1");
  EXPECT_EQ(back[0].created_unix_ms, a.created_unix_ms);
  EXPECT_EQ(back[1].flags, world::kProtectExplode);
  EXPECT_TRUE(back[1].owners.empty());
  s->for_each_edit(0, [&](const LoggedEdit& e) {
    EXPECT_EQ(e.keep.size(), 1u);
    EXPECT_EQ(e.keep[0].hi, keep[0].hi);
    return true;
  });
  const RegionWrite remove_a{.remove = {3}, .next_id = 12};
  s->append_edits({}, {}, &remove_a);  // a region change alone
  s.reset();
  const RegionTable after = open_world_store(where, {.read_only = true})->read_regions();
  ASSERT_EQ(after.regions.size(), 1u);
  EXPECT_EQ(after.regions[0].id, 9u);
  EXPECT_EQ(after.next_id, 12u) << "ids are never given twice, even after removals";
  s = open_world_store(where, {.seed = 1});
  const RegionWrite repair{.whole = true, .upsert = {a}, .next_id = 12};
  s->append_edits({}, {}, &repair);
  ASSERT_EQ(s->read_regions().regions.size(), 1u);
  EXPECT_EQ(s->read_regions().regions[0].id, 3u) << "a whole write replaces the table";
}

TEST_P(WorldStoreTest, ABatchWithADuplicateSeqWritesNothing) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  const world::Edit e = world::Explosion{{0, 0, 0}, 3, 1};
  s->append_edits(std::vector<LoggedEdit>{{1, 0, "", e}});
  const std::vector<LoggedEdit> bad{{2, 0, "", e}, {1, 0, "", e}, {3, 0, "", e}};
  EXPECT_THROW(s->append_edits(bad), StoreError);
  EXPECT_EQ(s->info().logged_edits, 1u);
  s->append_edits(std::vector<LoggedEdit>{{2, 0, "", e}});  // the store still works
  EXPECT_EQ(s->info().last_seq, 2u);
}

// One writing process per world: a second voxeld on it (or a restart while the old one
// still writes its last checkpoint) is refused naming the reason, and nothing is written;
// once the first is gone it opens. The same process's second connection is not a writer.
TEST_P(WorldStoreTest, ASecondWriterIsRefusedWhileTheFirstLives) {
  const std::string where = fresh_world();
  {
    auto first = open_world_store(where, {.seed = 1});
    auto own = open_world_store(where, {.seed = 1, .record_start = false});
    try {
      open_world_store(where, {.seed = 1});
      ADD_FAILURE() << "a second writer opened the world";
    } catch (const StoreError& e) {
      EXPECT_NE(std::string(e.what()).find("another voxeld is writing this world"),
                std::string::npos)
          << e.what();
    }
    EXPECT_EQ(first->info().starts, 1u);
    EXPECT_NO_THROW(open_world_store(where, {.read_only = true}));  // tools still read
  }
  EXPECT_NO_THROW(open_world_store(where, {.seed = 1}));
}

// CI saw "another voxeld is writing this world" when a test reopened a PostgreSQL world
// right after closing it: the server drops a session's lock only once its backend has seen
// the close. A writer that lets go within kWriterLockWait is waited for, not refused.
TEST_P(WorldStoreTest, AWriterOpeningAsThePreviousOneClosesWaitsForItsLock) {
  const std::string where = fresh_world();
  auto first = open_world_store(where, {.seed = 1});
  std::thread closer([&first] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    first.reset();
  });
  std::unique_ptr<WorldStore> second;
  EXPECT_NO_THROW(second = open_world_store(where, {.seed = 1}));
  closer.join();
  ASSERT_TRUE(second);
  EXPECT_EQ(second->info().starts, 2u);
}

// Appends whose outcome was in doubt (they failed, yet may have landed) and whose edits
// the pipeline undid go from the log with the next append that works.
TEST_P(WorldStoreTest, AnAppendForgetsTheDoubtfulOnesInItsTransaction) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  const world::Edit e = world::Explosion{{0, 0, 0}, 3, 1};
  std::vector<LoggedEdit> five;
  for (uint64_t seq = 1; seq <= 5; ++seq) five.push_back({seq, 0, "", e});
  s->append_edits(five);
  const std::vector<WorldStore::SeqRange> forget{{3, 4}};
  s->append_edits(std::vector<LoggedEdit>{{7, 0, "", e}}, forget);
  std::vector<uint64_t> seqs;
  s->for_each_edit(0, [&](const LoggedEdit& l) {
    seqs.push_back(l.seq);
    return true;
  });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{1, 2, 5, 7}));
}

TEST_P(WorldStoreTest, CheckpointsReplaceChunksAndTrimTheLog) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  std::vector<LoggedEdit> log;
  for (uint64_t seq = 1; seq <= 10; ++seq)
    log.push_back({seq, 0, "", world::Smooth{{0, 0, 0}, 2, 1}});
  s->append_edits(log);
  const world::Chunk a = full_chunk(1), b = full_chunk(2), air;
  std::vector<ChunkRecord> first{{{0, 0, 0}, 4, encode_chunk(a)},
                                 {{-1, 2, -3}, 4, encode_chunk(air)}};
  s->write_checkpoint(first, 4, 4);
  std::vector<ChunkRecord> second{{{0, 0, 0}, 9, encode_chunk(b)}};
  s->write_checkpoint(second, 9, 0);  // keep the log this time
  const WorldInfo i = s->info();
  EXPECT_EQ(i.checkpoint_seq, 9u);
  EXPECT_EQ(i.logged_edits, 6u);  // 5..10
  EXPECT_EQ(i.last_seq, 10u);
  EXPECT_EQ(i.modified_chunks, 2u);
  const auto r = s->read_chunk({0, 0, 0});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->seq, 9u);
  EXPECT_TRUE(*decode_chunk(r->samples) == b);
  const auto u = s->read_chunk({-1, 2, -3});
  ASSERT_TRUE(u);
  EXPECT_TRUE(*decode_chunk(u->samples) == air);
  EXPECT_FALSE(s->read_chunk({5, 5, 5}));
  size_t listed = 0;
  s->for_each_chunk([&](world::ChunkCoord, uint64_t) { ++listed; });
  EXPECT_EQ(listed, 2u);
}

TEST_P(WorldStoreTest, ACheckpointKeepsTheEditsOfTheHistoryWindow) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  std::vector<LoggedEdit> log;
  // Accepted at 100, 200, ..., 1000 ms; the clock went back once (seq 6 at 150 ms).
  for (uint64_t seq = 1; seq <= 10; ++seq)
    log.push_back({seq, seq == 6 ? 150 : static_cast<int64_t>(seq) * 100, "",
                   world::Smooth{{0, 0, 0}, 2, 1}});
  s->append_edits(log);
  const std::vector<ChunkRecord> chunks{{{0, 0, 0}, 8, encode_chunk(full_chunk(1))}};
  // Through 8, but nothing accepted at 450 ms or later, nor after it: 1..4 go.
  s->write_checkpoint(chunks, 8, LogTrim{8, 450});
  std::vector<uint64_t> seqs;
  s->for_each_edit(0, [&](const LoggedEdit& l) { return seqs.push_back(l.seq), true; });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{5, 6, 7, 8, 9, 10}));
  // A window past every edit: through the checkpoint, as without one.
  s->write_checkpoint(chunks, 8, LogTrim{8, 5000});
  seqs.clear();
  s->for_each_edit(0, [&](const LoggedEdit& l) { return seqs.push_back(l.seq), true; });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{9, 10}));
}

TEST_P(WorldStoreTest, AnEditStampedByAClockThatRanAheadHoldsNoHistoryBack) {
  auto s = open_world_store(fresh_world(), {.seed = 1});
  std::vector<LoggedEdit> log;
  const int64_t at[] = {100, 5000000, 200, 300};  // edit 2: a clock far ahead
  for (uint64_t seq = 1; seq <= 4; ++seq)
    log.push_back({seq, at[seq - 1], "", world::Smooth{{0, 0, 0}, 2, 1}});
  s->append_edits(log);
  s->write_checkpoint({}, 4, LogTrim{4, 250, 1000});
  std::vector<uint64_t> seqs;
  s->for_each_edit(0, [&](const LoggedEdit& l) { return seqs.push_back(l.seq), true; });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{4}));
}

TEST_P(WorldStoreTest, ReadOnlyToolsReadAWorldWhileItIsWritten) {
  const std::string where = fresh_world();
  auto writer = open_world_store(where, {.seed = 3});
  writer->append_edits(std::vector<LoggedEdit>{{1, 0, "bob", world::Paint{{1, 2, 3}, 2, 4}}});
  auto reader = open_world_store(where, {.read_only = true});
  EXPECT_EQ(reader->info().last_seq, 1u);
  writer->append_edits(std::vector<LoggedEdit>{{2, 0, "bob", world::Paint{{1, 2, 3}, 2, 5}}});
  EXPECT_EQ(reader->info().last_seq, 2u);
  EXPECT_EQ(reader->info().starts, 1u);  // a read-only open is not a start
  EXPECT_THROW(reader->append_edits(std::vector<LoggedEdit>{{3, 0, "", world::Paint{}}}),
               StoreError);
}

INSTANTIATE_TEST_SUITE_P(Backends, WorldStoreTest, ::testing::Values("sqlite", "postgresql"),
                         [](const auto& info) { return info.param; });

// PostgreSQL going away and coming back: the store fails with a clear error, then works
// again by itself (the connection is reopened).
TEST(PostgresStore, AStoreThatWentAwayWorksAgainWhenItIsBack) {
  test::PostgresServer server;
  auto s = open_world_store(server.create_database("gone"), {.seed = 1});
  const world::Edit e = world::Explosion{{0, 0, 0}, 3, 1};
  s->append_edits(std::vector<LoggedEdit>{{1, 0, "", e}});
  server.stop();
  try {
    s->append_edits(std::vector<LoggedEdit>{{2, 0, "", e}});
    FAIL() << "appended with the database down";
  } catch (const StoreError& err) {
    EXPECT_NE(std::string(err.what()).find("PostgreSQL"), std::string::npos) << err.what();
  }
  server.start();
  s->append_edits(std::vector<LoggedEdit>{{2, 0, "", e}});
  EXPECT_EQ(s->info().last_seq, 2u);
}

// The same migration of a schema-1 world as SQLite's, on PostgreSQL.
TEST(PostgresStore, ASchemaOneWorldIsMigratedAndKeepsItsChunks) {
  test::PostgresServer server;
  const std::string uri = server.create_database("schema1");
  server.sql("schema1",
             "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);"
             "CREATE TABLE edit_log (seq BIGINT PRIMARY KEY, at_ms BIGINT NOT NULL,"
             " author TEXT NOT NULL, edit BYTEA NOT NULL);"
             "CREATE TABLE chunks (x INTEGER NOT NULL, y INTEGER NOT NULL, z INTEGER NOT NULL,"
             " seq BIGINT NOT NULL, samples BYTEA NOT NULL, PRIMARY KEY (x, y, z));"
             "INSERT INTO meta VALUES ('schema_version', '1'), ('seed', '5'), ('starts', '1'),"
             " ('checkpoint_seq', '3');"
             "INSERT INTO chunks VALUES (1, 2, 3, 3, '\\x0100000000');");
  expect_schema_one_world_migrates(uri);
}

TEST(PostgresStore, RedactsThePasswordInMessages) {
  EXPECT_EQ(redact_uri("postgresql://voxel:secret@db.example:5432/world"),
            "postgresql://voxel:***@db.example:5432/world");
  EXPECT_EQ(redact_uri("postgresql:///world?host=/tmp"), "postgresql:///world?host=/tmp");
}

// A password given as a query parameter went into error messages and logs as it was.
TEST(PostgresStore, APasswordInTheQueryWasShownInMessages) {
  EXPECT_EQ(redact_uri("postgresql:///w?host=/tmp&password=secret&user=x"),
            "postgresql:///w?host=/tmp&password=***&user=x");
  EXPECT_EQ(redact_uri("postgresql://h/w?password=secret"), "postgresql://h/w?password=***");
  EXPECT_EQ(redact_uri("postgresql://u:pw@h/w?sslpassword=k&password=s"),
            "postgresql://u:***@h/w?sslpassword=k&password=***");
}

// --- SQLite files as an operator may find them ---

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void expect_refused(const fs::path& dir, const std::string& what) {
  const fs::path file = dir / kSqliteFileName;
  const std::string before = file_bytes(file);
  try {
    open_world_store(dir.string(), {.seed = 1});
    FAIL() << "opened " << what;
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
  }
  EXPECT_EQ(file_bytes(file), before) << what << " was written";
}

TEST(SqliteStore, AFileThatIsNotADatabaseIsRefusedAndLeftAlone) {
  const test::TempDir tmp("store_garbage");
  const fs::path dir = tmp / "world";
  fs::create_directories(dir);
  std::ofstream(dir / kSqliteFileName) << std::string(5000, 'x');
  expect_refused(dir, "a garbage file");
}

TEST(SqliteStore, ATruncatedFileIsRefusedAndLeftAlone) {
  const test::TempDir tmp("store_trunc");
  const fs::path dir = tmp / "world";
  {
    auto s = open_world_store(dir.string(), {.seed = 1});
    std::vector<ChunkRecord> chunks;
    for (int i = 0; i < 40; ++i) chunks.push_back({{i, 0, 0}, 1, encode_chunk(full_chunk(i))});
    s->write_checkpoint(chunks, 1, 0);
  }
  const fs::path file = dir / kSqliteFileName;
  ASSERT_FALSE(fs::exists(dir / (std::string(kSqliteFileName) + "-wal")) &&
               fs::file_size(dir / (std::string(kSqliteFileName) + "-wal")) > 0);
  fs::resize_file(file, fs::file_size(file) / 2);
  expect_refused(dir, "a truncated file");
}

TEST(SqliteStore, ANewerSchemaIsRefusedAndLeftAlone) {
  const test::TempDir tmp("store_newer");
  const fs::path dir = tmp / "world";
  open_world_store(dir.string(), {.seed = 1});
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / kSqliteFileName).c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE meta SET value = '99' WHERE key = 'schema_version'", nullptr,
                         nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  expect_refused(dir, "a schema from a newer version");
  try {
    open_world_store(dir.string(), {.seed = 1});
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 99 is newer"), std::string::npos);
  }
}

std::string fmt_hex(uint8_t byte) {
  static const char* digits = "0123456789abcdef";
  return {digits[byte >> 4], digits[byte & 15]};
}

void sql(const fs::path& dir, const char* query) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / kSqliteFileName).c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  EXPECT_EQ(sqlite3_exec(db, query, nullptr, nullptr, &error), SQLITE_OK) << (error ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

// A checkpoint killed after some of its short transactions: its rows (above the recorded
// checkpoint) are invisible to readers and deleted when a writer opens the world.
TEST(SqliteStore, AnUnfinishedCheckpointIsInvisibleAndDroppedWhenAWriterOpens) {
  const test::TempDir tmp("store_unfinished");
  const fs::path dir = tmp / "world";
  const world::Chunk a = full_chunk(1), b = full_chunk(2);
  {
    auto s = open_world_store(dir.string(), {.seed = 1});
    s->write_checkpoint(std::vector<ChunkRecord>{{{0, 0, 0}, 4, encode_chunk(a)}}, 4, 4);
  }
  const std::string insert = "INSERT INTO chunks (x, y, z, seq, samples) VALUES (0, 0, 0, 9, x'" +
                             [&] {
                               std::string hex;
                               for (uint8_t byte : encode_chunk(b)) hex += fmt_hex(byte);
                               return hex;
                             }() +
                             "'), (7, 7, 7, 9, x'0100000000')";
  sql(dir, insert.c_str());
  auto check = [&](WorldStore& s) {
    const auto r = s.read_chunk({0, 0, 0});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->seq, 4u);
    EXPECT_TRUE(*decode_chunk(r->samples) == a);
    EXPECT_FALSE(s.read_chunk({7, 7, 7}));
    EXPECT_EQ(s.info().modified_chunks, 1u);
    size_t listed = 0;
    s.for_each_chunk([&](world::ChunkCoord, uint64_t seq) {
      ++listed;
      EXPECT_EQ(seq, 4u);
    });
    EXPECT_EQ(listed, 1u);
  };
  check(*open_world_store(dir.string(), {.read_only = true}));
  check(*open_world_store(dir.string(), {.seed = 1}));
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / kSqliteFileName).c_str(), &db), SQLITE_OK);
  sqlite3_stmt* q = nullptr;
  sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM chunks", -1, &q, nullptr);
  ASSERT_EQ(sqlite3_step(q), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(q, 0), 1) << "the unfinished checkpoint's rows are still there";
  sqlite3_finalize(q);
  sqlite3_close(db);
}

// Appends back to back on one connection (the pipeline under a flood of edits) and a
// checkpoint of many small parts on another: each part gets SQLite's write lock between
// two appends (the busy handler tries every 250 us), so the checkpoint is not starved.
TEST(SqliteStore, ACheckpointIsNotStarvedByBackToBackAppends) {
  const test::TempDir tmp("store_starved");
  const fs::path dir = tmp / "world";
  auto appender = open_world_store(dir.string(), {.seed = 1});
  auto writer = open_world_store(dir.string(), {.seed = 1, .record_start = false});
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> appended{0};
  std::thread appends([&] {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    for (uint64_t seq = 1; !stop && std::chrono::steady_clock::now() < give_up; ++seq) {
      appender->append_edits(std::vector<LoggedEdit>{{seq, 0, "", world::Paint{{1, 2, 3}, 2, 4}}});
      appended = seq;
    }
  });
  while (appended < 20) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::vector<ChunkRecord> chunks;
  // Small rows, many parts: each part waits for the lock anew.
  const auto bytes = encode_chunk(world::Chunk{});
  for (int i = 0; i < 1024; ++i) chunks.push_back({{i, 0, 0}, 10, bytes});
  const auto start = std::chrono::steady_clock::now();
  EXPECT_NO_THROW(writer->write_checkpoint(chunks, 10, 0));
  const double took =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop = true;
  appends.join();
  // ~50 ms; SQLite's own busy timeout (sleeps of up to 100 ms) took 1.7-8 s here.
  EXPECT_LT(took, 1.0) << "the checkpoint waited for the write lock";
  EXPECT_EQ(writer->info().checkpoint_seq, 10u);
}

// A world of schema 1 (one row per chunk, yesterday's voxeld) is migrated by a writer and
// keeps its chunks; readers read it as it is.
TEST(SqliteStore, ASchemaOneWorldIsMigratedAndKeepsItsChunks) {
  const test::TempDir tmp("store_schema1");
  const fs::path dir = tmp / "world";
  fs::create_directories(dir);
  sql(dir,
      "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);"
      "CREATE TABLE edit_log (seq INTEGER PRIMARY KEY, at_ms INTEGER NOT NULL,"
      " author TEXT NOT NULL, edit BLOB NOT NULL);"
      "CREATE TABLE chunks (x INTEGER NOT NULL, y INTEGER NOT NULL, z INTEGER NOT NULL,"
      " seq INTEGER NOT NULL, samples BLOB NOT NULL, PRIMARY KEY (x, y, z));"
      "INSERT INTO meta VALUES ('schema_version', '1'), ('seed', '5'), ('starts', '1'),"
      " ('checkpoint_seq', '3');"
      "INSERT INTO chunks VALUES (1, 2, 3, 3, x'0100000000');");
  expect_schema_one_world_migrates(dir.string());
}

TEST(SqliteStore, ReadOnlyOpenOfAMissingWorldCreatesNothing) {
  const test::TempDir tmp("store_missing");
  const fs::path dir = tmp / "world";
  EXPECT_THROW(open_world_store(dir.string(), {.read_only = true}), StoreError);
  EXPECT_FALSE(fs::exists(dir));
}

}  // namespace
}  // namespace vox::store
