// The load tester's DecodeMemo: only a byte-identical encoding of the same (level, chunk)
// counts as already decoded, and the few most recent ones are kept.
#include "loadtest/decode_memo.hpp"

#include <gtest/gtest.h>

namespace vox::loadtest {
namespace {

TEST(DecodeMemo, KnowsOnlyTheSameBytesOfTheSameChunk) {
  DecodeMemo memo;
  const MemoKey key{0, {1, -2, 3}};
  const std::vector<uint8_t> good{1, 2, 3, 4, 5};
  EXPECT_FALSE(memo.known_good(key, good));
  memo.remember(key, good);
  EXPECT_TRUE(memo.known_good(key, good));
  EXPECT_FALSE(memo.known_good({0, {1, -2, 4}}, good)) << "another chunk";
  EXPECT_FALSE(memo.known_good({1, {1, -2, 3}}, good)) << "another level";
  std::vector<uint8_t> flipped = good;
  flipped[2] ^= 0x10;
  EXPECT_FALSE(memo.known_good(key, flipped)) << "one bit differs";
  EXPECT_FALSE(memo.known_good(key, std::vector<uint8_t>{1, 2, 3, 4})) << "a prefix";
}

// The bug: coarse chunks were decoded by every player every time (wire versions differ
// per session and seams variants coexist), which made the load tester the bottleneck of a
// LOD load test.
TEST(DecodeMemo, KeepsSeveralVariantsOfOneCoarseChunkAndForgetsTheOldest) {
  DecodeMemo memo;
  const MemoKey key{3, {0, 0, 0}};
  std::vector<std::vector<uint8_t>> variants;
  for (uint8_t i = 0; i <= DecodeMemo::kKept; ++i) variants.push_back({i, 7, 7});
  for (size_t i = 0; i < DecodeMemo::kKept; ++i) memo.remember(key, variants[i]);
  for (size_t i = 0; i < DecodeMemo::kKept; ++i) EXPECT_TRUE(memo.known_good(key, variants[i]));
  memo.remember(key, variants[0]);  // seen again: now the newest
  memo.remember(key, variants[DecodeMemo::kKept]);
  EXPECT_TRUE(memo.known_good(key, variants[DecodeMemo::kKept]));
  EXPECT_TRUE(memo.known_good(key, variants[0]));
  EXPECT_FALSE(memo.known_good(key, variants[1])) << "the oldest went";
}

TEST(DecodeMemo, KeepsOnlyTheNewestFewVersionsOfALevelZeroChunk) {
  DecodeMemo memo;
  const MemoKey key{0, {4, 0, 4}};
  std::vector<std::vector<uint8_t>> versions;
  for (uint8_t i = 0; i < 4; ++i) versions.push_back({i, 1});
  for (const auto& v : versions) memo.remember(key, v);
  EXPECT_TRUE(memo.known_good(key, versions[3]));
  EXPECT_TRUE(memo.known_good(key, versions[2]));
  EXPECT_FALSE(memo.known_good(key, versions[1])) << "only " << DecodeMemo::kKeptLevel0 << " kept";
}

}  // namespace
}  // namespace vox::loadtest
