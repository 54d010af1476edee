// Undoing logged edits (server/world/edit_undo.hpp): players A and B edit the same chunks
// in turn; undoing B's edits leaves, byte for byte, the world of A's edits alone. A smooth
// of A's that read B's terrain across a chunk border is recomputed too; chunks no undone
// edit reached are left out; the bound on chunks holds.
#include "server/world/edit_undo.hpp"

#include <gtest/gtest.h>

#include <map>

#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"
#include "tests/replay_util.hpp"

namespace vox::world {
namespace {

struct Authored {
  char who;
  Edit edit;
};

// The world after `edits` but those of `skip`, from the generator: every chunk they reach.
std::map<ChunkCoord, Chunk> replayed(const std::vector<Authored>& edits, char skip,
                                     const TerrainGenerator& gen) {
  return test::replayed_without(edits, skip, gen);
}

UndoResult undo(const std::vector<Authored>& edits, char who, const TerrainGenerator& gen,
                size_t max_chunks = 0) {
  std::vector<LoggedStep> log;
  uint64_t seq = 0;
  for (const Authored& a : edits) log.push_back({++seq, &a.edit, {}, a.who == who, a.who == who});
  return undo_edits(
      steps_of(log), gen, [](ChunkCoord) { return std::nullopt; }, max_chunks);
}

TEST(EditUndo, UndoingBsEditsLeavesExactlyTheWorldOfAsAlone) {
  const TerrainGenerator gen(7);
  const float y = static_cast<float>(gen.height_at(16, 16));
  // Turn by turn on the same few chunks, across the border at x = 32 (a smooth of A's
  // reads what B dug there).
  std::vector<Authored> edits = {
      {'A', Brush{{20, y, 16}, 6, 0.9f, false, 3}},
      {'B', Explosion{{30, y, 16}, 7, 1}},
      {'A', Paint{{28, y, 16}, 5, 4}},
      {'B', Stamp{Stamp::Shape::kBox, {34, y - 4, 10}, {40, y + 6, 20}, {}, 0, true, 5}},
      {'A', Smooth{{33, y, 16}, 6, 0.7f}},
      {'B', Brush{{36, y, 20}, 4, 0.5f, true, 0}},
      {'A', Explosion{{60, y, 16}, 3, 1}},  // far from B: not recomputed
  };
  const UndoResult r = undo(edits, 'B', gen);
  EXPECT_FALSE(r.too_many);
  EXPECT_EQ(r.changed, 3u);
  const std::map<ChunkCoord, Chunk> want = replayed(edits, 'B', gen);
  ASSERT_FALSE(r.chunks.empty());
  for (const auto& [c, chunk] : r.chunks) {
    ASSERT_TRUE(want.count(c)) << c.x << "," << c.y << "," << c.z;
    EXPECT_TRUE(chunk == want.at(c)) << "chunk " << c.x << "," << c.y << "," << c.z;
  }
  // The far explosion's chunk (x 59..63 within chunk 1) is no undone edit's and was not
  // read by one's: left out unless an undone edit reached it too.
  const std::map<ChunkCoord, Chunk> all_b = replayed(edits, 0, gen);
  size_t differs = 0;
  for (const auto& [c, chunk] : want) differs += chunk == all_b.at(c) ? 0 : 1;
  EXPECT_GT(differs, 0u) << "B's edits changed nothing: the test proves nothing";
}

TEST(EditUndo, NothingToUndoRecomputesNothingAndTheBoundHolds) {
  const TerrainGenerator gen(7);
  const float y = static_cast<float>(gen.height_at(16, 16));
  std::vector<Authored> edits = {{'A', Explosion{{16, y, 16}, 6, 1}},
                                 {'B', Explosion{{100, y, 100}, 20, 1}}};
  const UndoResult none = undo(edits, 'C', gen);
  EXPECT_TRUE(none.chunks.empty());
  EXPECT_EQ(none.replayed, 0u);
  const UndoResult capped = undo(edits, 'B', gen, 2);
  EXPECT_TRUE(capped.too_many);
  EXPECT_TRUE(capped.chunks.empty());
  const UndoResult b = undo(edits, 'B', gen);
  EXPECT_EQ(b.replayed, 0u);  // A's explosion is elsewhere: nothing to apply again
  for (const auto& [c, chunk] : b.chunks) EXPECT_TRUE(chunk == gen.generate(c));
}

}  // namespace
}  // namespace vox::world
