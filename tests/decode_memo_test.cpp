// The load tester's DecodeMemo: only a byte-identical encoding of the same chunk version
// counts as already decoded.
#include "loadtest/decode_memo.hpp"

#include <gtest/gtest.h>

namespace vox::loadtest {
namespace {

TEST(DecodeMemo, KnowsOnlyTheSameBytesOfTheSameVersion) {
  DecodeMemo memo;
  const client::ChunkKey key{1, -2, 3};
  const std::vector<uint8_t> good{1, 2, 3, 4, 5};
  EXPECT_FALSE(memo.known_good(key, 7, good));
  memo.remember(key, 7, good);
  EXPECT_TRUE(memo.known_good(key, 7, good));
  EXPECT_FALSE(memo.known_good(key, 8, good)) << "another version";
  EXPECT_FALSE(memo.known_good({1, -2, 4}, 7, good)) << "another chunk";
  std::vector<uint8_t> flipped = good;
  flipped[2] ^= 0x10;
  EXPECT_FALSE(memo.known_good(key, 7, flipped)) << "one bit differs";
  EXPECT_FALSE(memo.known_good(key, 7, std::vector<uint8_t>{1, 2, 3, 4})) << "a prefix";
  // A newer version replaces the entry; an older one does not.
  memo.remember(key, 9, flipped);
  EXPECT_FALSE(memo.known_good(key, 7, good));
  EXPECT_TRUE(memo.known_good(key, 9, flipped));
  memo.remember(key, 8, good);
  EXPECT_TRUE(memo.known_good(key, 9, flipped));
  EXPECT_FALSE(memo.known_good(key, 8, good));
}

}  // namespace
}  // namespace vox::loadtest
