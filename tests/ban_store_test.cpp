// The world's bans in both backends (SQLite beside the world, a real PostgreSQL): stored,
// replaced, removed, read back by another connection (a cluster's other node), ended ones
// deleted, rows that are not bans skipped, worlds of one database kept apart.
#include "server/store/ban_store.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "server/store/sqlite_store.hpp"
#include "tests/postgres_server.hpp"
#include "tests/temp_dir.hpp"

namespace vox::store {
namespace {

Ban ban(Ban::Kind kind, const std::string& target, int64_t until_ms = 0) {
  Ban b;
  b.kind = kind;
  b.target = target;
  b.reason = "griefing spawn";
  b.created_by = "root";
  b.created_ms = 1000;
  b.until_ms = until_ms;
  return b;
}

class BanStoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  static void TearDownTestSuite() { postgres_.reset(); }
  std::string fresh_world() {
    static int n = 0;
    if (GetParam() == "sqlite") {
      const std::string where = (tmp_.emplace("bans") / "world").string();
      open_world_store(where, {});  // the world exists first, as voxeld opens it
      return where;
    }
    if (!postgres_) postgres_ = std::make_unique<test::PostgresServer>();
    return postgres_->create_database("bans" + std::to_string(n++));
  }
  static std::unique_ptr<test::PostgresServer> postgres_;
  std::optional<test::TempDir> tmp_;
};
std::unique_ptr<test::PostgresServer> BanStoreTest::postgres_;

TEST_P(BanStoreTest, BansAreStoredReplacedRemovedAndSeenByAnotherConnection) {
  const std::string where = fresh_world();
  auto a = open_ban_store(where);
  auto b = open_ban_store(where);  // another node's connection
  EXPECT_TRUE(b->read(0).bans.empty());
  a->put(ban(Ban::Kind::kPlayer, "mallory"));
  a->put(ban(Ban::Kind::kAddress, "203.0.113.7", 5000));
  Ban replaced = ban(Ban::Kind::kPlayer, "mallory");
  replaced.reason = "second time";
  a->put(replaced);
  const BanStore::Read read = b->read(2000);
  ASSERT_EQ(read.bans.size(), 2u);
  EXPECT_EQ(read.skipped, 0u);
  EXPECT_EQ(read.bans[0], ban(Ban::Kind::kAddress, "203.0.113.7", 5000));
  EXPECT_EQ(read.bans[1], replaced);
  EXPECT_TRUE(b->remove(Ban::Kind::kPlayer, "mallory"));
  EXPECT_FALSE(b->remove(Ban::Kind::kPlayer, "mallory"));
  EXPECT_FALSE(b->remove(Ban::Kind::kAddress, "mallory"));
  // The address ban ended at 5000: a read after it deletes it.
  EXPECT_TRUE(a->read(5000).bans.empty());
  EXPECT_FALSE(a->remove(Ban::Kind::kAddress, "203.0.113.7"));
}

TEST_P(BanStoreTest, TheWorldsOfOneDatabaseKeepTheirOwnBans) {
  const std::string where = fresh_world();
  open_ban_store(where, "north")->put(ban(Ban::Kind::kPlayer, "mallory"));
  EXPECT_TRUE(open_ban_store(where, "south")->read(0).bans.empty());
  EXPECT_EQ(open_ban_store(where, "north")->read(0).bans.size(), 1u);
}

INSTANTIATE_TEST_SUITE_P(Backends, BanStoreTest, ::testing::Values("sqlite", "postgresql"),
                         [](const auto& info) { return info.param; });

TEST(BanStore, RowsThatAreNotBansAreSkippedAndCounted) {
  test::TempDir dir("bans");
  const std::string where = (dir / "world").string();
  open_world_store(where, {});
  open_ban_store(where)->put(ban(Ban::Kind::kPlayer, "ok"));
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "world" / kSqliteFileName).c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "INSERT INTO bans VALUES ('', 'ghost', 'x', '', '', 0, 0);"
                         "INSERT INTO bans VALUES ('', 'player', '', '', '', 0, 0);"
                         "INSERT INTO bans VALUES ('', 'player', 'bad\nid', '', '', 0, 0);"
                         "INSERT INTO bans VALUES ('', 'player', 'textual', '', '', 0, 'abc');"
                         "INSERT INTO bans VALUES ('', 'player', 'long', "
                         "replace(hex(zeroblob(150)), '0', 'x'), '', 0, 0);",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  const BanStore::Read read = open_ban_store(where)->read(0);
  ASSERT_EQ(read.bans.size(), 1u);
  EXPECT_EQ(read.bans[0].target, "ok");
  EXPECT_EQ(read.skipped, 5u);
}

TEST(BanStore, AWorldDirectoryWithoutAWorldIsRefused) {
  test::TempDir dir("bans");
  EXPECT_THROW(open_ban_store((dir / "nothing").string()), StoreError);
}

}  // namespace
}  // namespace vox::store
