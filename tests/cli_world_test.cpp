// voxel-cli world info|log|verify on a world written through the store: what an operator
// reads, and verify telling a good checkpoint from a bad one.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

#include "client-cli/commands.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/world_store.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/temp_dir.hpp"

namespace vox::cli {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int code;
  std::string out, err;
};
CliRun cli(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const int code = run_cli(args, out, err);
  return {code, out.str(), err.str()};
}

class CliWorld : public ::testing::Test {
 protected:
  void SetUp() override {
    auto s = store::open_world_store(dir_.string(), {.seed = 5});
    const world::TerrainGenerator gen(5);
    const float y = gen.height_at(3, 3);
    edits_ = {world::Explosion{{3, y, 3}, 6, 1}, world::Brush{{30, y, 3}, 5, 0.8f, false, 2},
              world::Smooth{{31, y, 3}, 4, 0.5f}};
    std::vector<store::LoggedEdit> log;
    for (size_t i = 0; i < edits_.size(); ++i)
      log.push_back(
          {i + 1, 1764633600000 + static_cast<int64_t>(i), i == 1 ? "alice" : "", edits_[i]});
    s->append_edits(log);
  }

  // Checkpoints the chunks the first two edits changed, through seq 2, as the server would;
  // `corrupt` flips one sample of one of them first.
  void checkpoint_first_two(bool corrupt) {
    world::ChunkMap map;
    const world::TerrainGenerator gen(5);
    std::vector<world::ChunkCoord> changed;
    for (size_t i = 0; i < 2; ++i) {
      auto c = world::replay_edit(map, gen, edits_[i]);
      changed.insert(changed.end(), c.begin(), c.end());
    }
    ASSERT_FALSE(changed.empty());
    std::vector<store::ChunkRecord> records;
    for (const auto& c : changed) {
      world::Chunk chunk = *map.find(c);
      if (corrupt && records.empty()) chunk.set(0, 0, 0, {1234, 3});
      records.push_back({c, 2, store::encode_chunk(chunk)});
    }
    store::open_world_store(dir_.string(), {})->write_checkpoint(records, 2, 0);
  }

  test::TempDir tmp_{"cli_world"};
  const fs::path dir_ = tmp_ / "world";  // the store makes it
  std::vector<world::Edit> edits_;
};

TEST_F(CliWorld, InfoAndLogShowWhatAnOperatorNeeds) {
  const CliRun info = cli({"world", "info", dir_.string()});
  EXPECT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("seed:           5"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("last sequence:  3"), std::string::npos) << info.out;
  const CliRun log = cli({"world", "log", dir_.string(), "--since", "1"});
  EXPECT_EQ(log.code, 0) << log.err;
  EXPECT_EQ(log.out.find("1  "), std::string::npos) << "--since 1 shows 2 and 3 only";
  EXPECT_NE(log.out.find("2  2025-12-02T00:00:00.001Z  alice  brush at (30,"), std::string::npos)
      << log.out;
  EXPECT_NE(log.out.find("3  2025-12-02T00:00:00.002Z  -  smooth"), std::string::npos) << log.out;
}

TEST_F(CliWorld, HistoryListsAPlayersEditsInABoxAndTimeAndSaysHowFarBackTheLogReaches) {
  const std::string w = dir_.string();
  const CliRun all = cli({"world", "history", w});
  EXPECT_EQ(all.code, 0) << all.err;
  EXPECT_NE(all.out.find("3 edits: - 2, alice 1"), std::string::npos) << all.out;
  EXPECT_NE(all.out.find("reaches back to edit 1 (2025-12-02T00:00:00.000Z), the world's first"),
            std::string::npos)
      << all.out;
  const CliRun alice = cli({"world", "history", w, "--player", "alice", "--plan"});
  EXPECT_NE(alice.out.find("rollback plan: undoing these 1 edits recomputes"), std::string::npos)
      << alice.out;
  EXPECT_NE(alice.out.find("2  2025-12-02T00:00:00.001Z  alice  brush"), std::string::npos);
  EXPECT_NE(alice.out.find("1 edit: alice 1"), std::string::npos) << alice.out;
  // The explosion at x = 3 (radius 6) touches x 0..9; the brush and the smooth do not.
  const CliRun box = cli({"world", "history", w, "--min", "0,-1000,0", "--max", "9,1000,9"});
  EXPECT_NE(box.out.find("1 edit: - 1"), std::string::npos) << box.out;
  const CliRun span = cli({"world", "history", w, "--since", "2025-12-02T00:00:00", "--until",
                           "2025-12-02"});  // both midnight: edit 1 only
  EXPECT_NE(span.out.find("1 edit: - 1"), std::string::npos) << span.out;
  EXPECT_NE(cli({"world", "history", w, "--since", "1h"}).out.find("0 edits"), std::string::npos);
  EXPECT_EQ(cli({"world", "history", w, "--since", "yesterday"}).code, 2);
  EXPECT_EQ(cli({"world", "history", w, "--since", "2026"}).code, 2);  // a time? say which
  EXPECT_EQ(cli({"world", "history", w, "--since", "2025-02-30"}).code, 2);
  EXPECT_EQ(cli({"world", "history", w, "--since", "2025-12-0 1"}).code, 2);
  EXPECT_EQ(cli({"world", "history", w, "--min", "0,0,0"}).code, 2);
  store::open_world_store(w, {})->write_checkpoint({}, 2, 2);  // trims 1..2
  EXPECT_NE(cli({"world", "history", w}).out.find("reaches back to edit 3 ("), std::string::npos);
}

TEST_F(CliWorld, VerifyAcceptsTheServersCheckpointsAndNamesABadOne) {
  checkpoint_first_two(false);
  const CliRun good = cli({"world", "verify", dir_.string()});
  EXPECT_EQ(good.code, 0) << good.err;
  EXPECT_NE(good.out.find("3 logged edits replayed onto the seed"), std::string::npos) << good.out;
  EXPECT_NE(good.out.find("all match"), std::string::npos) << good.out;
  checkpoint_first_two(true);
  const CliRun bad = cli({"world", "verify", dir_.string()});
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.err.find("differs from the log"), std::string::npos) << bad.err;
}

TEST_F(CliWorld, AMissingWorldOrActionIsAClearErrorAndCreatesNothing) {
  const fs::path missing = dir_ / "nope";
  const CliRun r = cli({"world", "info", missing.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no such world"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(missing));
  EXPECT_EQ(cli({"world", "frobnicate", dir_.string()}).code, 2);
  EXPECT_EQ(cli({"world"}).code, 2);
}

}  // namespace
}  // namespace vox::cli
