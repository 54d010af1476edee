// The history a world keeps for rollbacks (store/world_history.hpp), on both backends:
// rolling back one player's edits gives exactly the world of the others' alone; the
// rollback, logged as a record, survives a restart (the pipeline replays it) and can be
// undone; the base moves past the window, skipping what records left out; a trim of the
// whole log drops the base, and the next checkpoint starts it again.
#include "server/store/world_history.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <map>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/edit_codec.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"
#include "server/world/edit_undo.hpp"
#include "tests/postgres_server.hpp"
#include "tests/replay_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::store {
namespace {

using world::ChunkCoord;

constexpr uint64_t kSeed = 7;

struct Authored {
  std::string who;
  world::Edit edit;
  int64_t at_ms = 0;
};

// Turn by turn on the same chunks, across the border at x = 32 (A's smooth reads what B
// dug there), and one of A's far from B's.
std::vector<Authored> turns(const world::TerrainGenerator& gen, int64_t at_ms) {
  const float y = static_cast<float>(gen.height_at(16, 16));
  return {
      {"A", world::Brush{{20, y, 16}, 6, 0.9f, false, 3}, at_ms},
      {"B", world::Explosion{{30, y, 16}, 7, 1}, at_ms},
      {"A", world::Paint{{28, y, 16}, 5, 4}, at_ms},
      {"B",
       world::Stamp{world::Stamp::Shape::kBox, {34, y - 4, 10}, {40, y + 6, 20}, {}, 0, true, 5},
       at_ms},
      {"A", world::Smooth{{33, y, 16}, 6, 0.7f}, at_ms},
      {"B", world::Brush{{36, y, 20}, 4, 0.5f, true, 0}, at_ms},
      {"A", world::Explosion{{60, y, 16}, 3, 1}, at_ms}};
}

uint64_t append(WorldStore& s, const std::vector<Authored>& edits, uint64_t first_seq) {
  std::vector<LoggedEdit> log;
  for (const Authored& a : edits)
    log.push_back({.seq = first_seq++, .unix_ms = a.at_ms, .author = a.who, .edit = a.edit});
  s.append_edits(log);
  return first_seq - 1;
}

uint64_t append_rollback(WorldStore& s, uint64_t seq, std::vector<uint64_t> undoes) {
  LoggedEdit r{.seq = seq, .unix_ms = 1, .author = "admin"};
  r.undoes = std::move(undoes);
  s.append_edits(std::span(&r, 1));
  return seq;
}

// The edits not by `skip`, replayed onto the seed: every chunk any edit reached.
std::map<ChunkCoord, world::Chunk> replayed(const std::vector<Authored>& edits,
                                            const std::string& skip,
                                            const world::TerrainGenerator& gen) {
  return test::replayed_without(edits, skip, gen);
}

void expect_chunks(const std::vector<std::pair<ChunkCoord, world::Chunk>>& got,
                   const std::map<ChunkCoord, world::Chunk>& want) {
  ASSERT_FALSE(got.empty());
  for (const auto& [c, chunk] : got) {
    ASSERT_TRUE(want.count(c)) << c.x << "," << c.y << "," << c.z;
    EXPECT_TRUE(chunk == want.at(c)) << "chunk " << c.x << "," << c.y << "," << c.z;
  }
}

int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Rolls B back, logs it, checks the world of A alone; undoes the rollback, checks both.
void roll_back_and_undo(WorldStore& s) {
  const world::TerrainGenerator gen(kSeed);
  const std::vector<Authored> edits = turns(gen, now_ms());
  const uint64_t last = append(s, edits, 1);
  const RollbackOutcome plan = prepare_rollback(s, gen, {.player = "B"}, last, true, 0);
  ASSERT_TRUE(plan.refusal.empty()) << plan.refusal;
  EXPECT_EQ(plan.undoes, (std::vector<uint64_t>{2, 4, 6}));
  EXPECT_EQ(plan.edits, 3u);
  EXPECT_TRUE(plan.recomputed.empty());
  const RollbackOutcome r = prepare_rollback(s, gen, {.player = "B"}, last, false, 0);
  EXPECT_EQ(r.chunks, plan.chunks);
  expect_chunks(r.recomputed, replayed(edits, "B", gen));
  const uint64_t record = append_rollback(s, last + 1, r.undoes);
  LoggedEdit logged;
  s.for_each_rollback(0, [&](const LoggedEdit& x) { return logged = x, false; });
  ASSERT_EQ(logged.undoes, r.undoes);
  expect_chunks(replay_rollback(s, gen, logged), replayed(edits, "B", gen));
  // B's edits are out: rolling B back again finds nothing.
  EXPECT_TRUE(prepare_rollback(s, gen, {.player = "B"}, record, true, 0).undoes.empty());
  const RollbackOutcome back = prepare_rollback(s, gen, {.undo_record = record}, record, false, 0);
  ASSERT_TRUE(back.refusal.empty()) << back.refusal;
  EXPECT_EQ(back.edits, 3u);
  expect_chunks(back.recomputed, replayed(edits, "", gen));
  const uint64_t again = append_rollback(s, record + 1, {record});
  EXPECT_NE(prepare_rollback(s, gen, {.undo_record = record}, again, true, 0).refusal, "");
  // The log lists the records among the edits, in order.
  std::vector<uint64_t> seqs;
  s.for_each_edit(0, [&](const LoggedEdit& e) { return seqs.push_back(e.seq), true; });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{1, 2, 3, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(s.info().last_seq, 9u);
}

TEST(History, RollingBackBGivesTheWorldOfAAloneAndUndoingItBringsBBack) {
  const test::TempDir tmp("history_ab");
  auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
  EXPECT_EQ(s->info().base_seq, 0u);
  roll_back_and_undo(*s);
}

TEST(History, RollingBackBGivesTheWorldOfAAloneOnPostgres) {
  auto s = open_world_store(test::fresh_shared_database("history"), {.seed = kSeed});
  EXPECT_EQ(s->info().base_seq, 0u);
  roll_back_and_undo(*s);
}

// The world the pipeline restores holds the rollback: replayed from the history at start.
TEST(History, ALoggedRollbackIsReplayedByARestart) {
  const test::TempDir tmp("history_restart");
  const world::TerrainGenerator gen(kSeed);
  const std::vector<Authored> edits = turns(gen, now_ms());
  {
    auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
    const uint64_t last = append(*s, edits, 1);
    const RollbackOutcome r = prepare_rollback(*s, gen, {.player = "B"}, last, true, 0);
    append_rollback(*s, last + 1, r.undoes);
  }
  auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
  pipeline::WorldPipeline p(
      pipeline::PipelineConfig{.seed = kSeed, .threads = 2, .store = s.get()});
  const std::map<ChunkCoord, world::Chunk> want = replayed(edits, "B", gen);
  size_t compared = 0;
  p.inspect([&](const world::ChunkMap& map) {
    for (const auto& [c, chunk] : want) {
      const world::Chunk* got = map.find(c);
      if (!got) continue;
      ++compared;
      EXPECT_TRUE(*got == chunk) << "chunk " << c.x << "," << c.y << "," << c.z;
    }
  });
  EXPECT_EQ(compared, want.size());
}

// Old edits leave the window: the base takes them, but for those a record left out.
void base_moves(WorldStore& s) {
  const world::TerrainGenerator gen(kSeed);
  const int64_t now = now_ms(), old = now - int64_t{10} * 24 * 3600 * 1000;
  const std::vector<Authored> before = turns(gen, old);
  uint64_t last = append(s, before, 1);
  last = append_rollback(s, last + 1, {2, 4, 6});  // B's, rolled back a while ago
  const float y = static_cast<float>(gen.height_at(16, 16));
  const std::vector<Authored> recent = {{"A", world::Explosion{{31, y, 16}, 8, 1}, now}};
  last = append(s, recent, last + 1);
  s.write_checkpoint({}, last, LogTrim{0});
  ChunkEncoder encoder;
  const LogTrim window(last, now - int64_t{7} * 24 * 3600 * 1000, now + 3600 * 1000);
  const HistoryStep step = advance_history(s, gen, window, last, encoder);
  EXPECT_FALSE(step.reset);
  EXPECT_EQ(step.through, 8u);  // the old edits and the record
  EXPECT_EQ(step.edits, 4u);    // A's: B's were left out
  EXPECT_EQ(s.info().base_seq, 8u);
  EXPECT_EQ(advance_history(s, gen, window, last, encoder).through, 0u) << "moved twice";
  std::vector<uint64_t> seqs;
  s.for_each_edit(0, [&](const LoggedEdit& e) { return seqs.push_back(e.seq), true; });
  EXPECT_EQ(seqs, (std::vector<uint64_t>{9}));
  // Rolling the recent edit back gives the base: the old edits of A alone.
  const RollbackOutcome r = prepare_rollback(s, gen, {.player = "A"}, last, false, 0);
  EXPECT_EQ(r.undoes, (std::vector<uint64_t>{9}));
  expect_chunks(r.recomputed, replayed(before, "B", gen));
  // What the history no longer holds is refused, saying how far back it goes.
  const RollbackOutcome early =
      prepare_rollback(s, gen, {.player = "A", .since_ms = old}, last, true, 0);
  EXPECT_NE(early.refusal.find("reaches back only to edit 9"), std::string::npos) << early.refusal;
  EXPECT_NE(prepare_rollback(s, gen, {.undo_record = 8}, last, true, 0).refusal, "");
}

TEST(History, TheBaseTakesTheEditsLeavingTheWindowButThoseRolledBack) {
  const test::TempDir tmp("history_base");
  auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
  base_moves(*s);
}

TEST(History, TheBaseTakesTheEditsLeavingTheWindowOnPostgres) {
  auto s = open_world_store(test::fresh_shared_database("history_base"), {.seed = kSeed});
  base_moves(*s);
}

TEST(History, TrimmingTheWholeLogDropsTheBaseAndTheNextCheckpointStartsItAgain) {
  const test::TempDir tmp("history_trim");
  const world::TerrainGenerator gen(kSeed);
  auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
  const uint64_t last = append(*s, turns(gen, now_ms()), 1);
  s->write_checkpoint({}, last, LogTrim{last});
  EXPECT_FALSE(s->info().base_seq.has_value());
  const RollbackOutcome r = prepare_rollback(*s, gen, {.player = "B"}, last, true, 0);
  EXPECT_NE(r.refusal.find("keeps no history"), std::string::npos) << r.refusal;
  ChunkEncoder encoder;
  // Where the whole log is kept (an audit trail), nothing is trimmed to start a base.
  EXPECT_FALSE(advance_history(*s, gen, LogTrim{0}, last, encoder).reset);
  EXPECT_FALSE(s->info().base_seq.has_value());
  const int64_t now = now_ms();
  const HistoryStep step = advance_history(*s, gen, LogTrim(last, now - 1000, now), last, encoder);
  EXPECT_TRUE(step.reset);
  EXPECT_EQ(s->info().base_seq, last);
}

// A restart from the checkpoint replays a record logged after it: the base must not pass
// an edit that record reaches, or the replay would not see that edit go.
TEST(History, TheBaseStopsBeforeWhatARecordPastTheCheckpointReaches) {
  const test::TempDir tmp("history_floor");
  const world::TerrainGenerator gen(kSeed);
  auto s = open_world_store((tmp / "world").string(), {.seed = kSeed});
  const int64_t now = now_ms(), old = now - int64_t{10} * 24 * 3600 * 1000;
  const uint64_t last = append(*s, turns(gen, old), 1);
  s->write_checkpoint({}, last, LogTrim{0});
  append_rollback(*s, last + 1, {4, 6});  // after the checkpoint
  ChunkEncoder encoder;
  const HistoryStep step = advance_history(
      *s, gen, LogTrim(last, now - int64_t{7} * 24 * 3600 * 1000, now + 3600 * 1000), last,
      encoder);
  EXPECT_EQ(step.through, 3u);
  EXPECT_EQ(s->info().base_seq, 3u);
}

TEST(History, SeqListsRoundTripAndHostileOnesAreRefused) {
  const std::vector<uint64_t> seqs = {1, 5, 6, 1'000'000'000'000, UINT64_MAX};
  EXPECT_EQ(decode_seq_list(encode_seq_list(seqs)), seqs);
  const std::vector<std::vector<uint8_t>> bad = {
      {},
      {1, 1, 1},                                        // an edit's format
      {kRollbackFormat, 0},                             // none
      {kRollbackFormat, 2, 5, 0},                       // not ascending
      {kRollbackFormat, 2, 5},                          // cut short
      {kRollbackFormat, 1, 5, 9},                       // bytes past the end
      {kRollbackFormat, 0xff, 0xff, 0xff, 0xff, 0x7f},  // more than there are bytes for
      {kRollbackFormat, 1, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f},
  };
  for (const auto& b : bad) {
    std::string why;
    EXPECT_FALSE(decode_seq_list(b, &why).has_value()) << b.size();
    EXPECT_FALSE(why.empty());
  }
}

TEST(History, ARecordUndoneByALaterOneUndoesNothing) {
  const std::vector<uint64_t> a = {1, 2}, b = {10}, c = {11};
  std::vector<world::RollbackMark> marks = {{10, a}, {11, b}};
  EXPECT_EQ(world::excluded_by(marks), (std::unordered_set<uint64_t>{10}));
  marks.push_back({12, c});
  EXPECT_EQ(world::excluded_by(marks), (std::unordered_set<uint64_t>{11, 1, 2}));
}

}  // namespace
}  // namespace vox::store
