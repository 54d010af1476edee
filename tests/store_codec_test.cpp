// The store's records: edits and chunk samples round-trip bit for bit, stay small, and
// hostile bytes are refused with an error, never a crash or a huge allocation.
#include <gtest/gtest.h>
#include <zstd.h>

#include <random>

#include "server/store/chunk_codec.hpp"
#include "server/store/edit_codec.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/store_test_util.hpp"

namespace vox::store {
namespace {

TEST(EditCodec, EveryKindRoundTripsBitForBitInAFewTensOfBytes) {
  for (const world::Edit& e : test::one_edit_of_each_kind()) {
    const auto bytes = encode_edit(e);
    EXPECT_LE(bytes.size(), 32u) << describe_edit(e);
    std::string why;
    const auto back = decode_edit(bytes, &why);
    ASSERT_TRUE(back) << why;
    EXPECT_EQ(back->index(), e.index());
    EXPECT_EQ(encode_edit(*back), bytes) << describe_edit(e);
  }
}

TEST(EditCodec, RefusesEveryTruncationAndAnyTrailingByte) {
  for (const world::Edit& e : test::one_edit_of_each_kind()) {
    const auto bytes = encode_edit(e);
    for (size_t n = 0; n < bytes.size(); ++n)
      EXPECT_FALSE(decode_edit({bytes.data(), n})) << describe_edit(e) << " cut at " << n;
    auto longer = bytes;
    longer.push_back(0);
    EXPECT_FALSE(decode_edit(longer)) << describe_edit(e);
  }
}

// An edit clipped by protected regions keeps its boxes (format 2); every truncation and
// a bad count or an inverted box are refused.
TEST(EditCodec, AClippedEditKeepsItsBoxesAndEveryDamageIsRefused) {
  const std::vector<world::VoxelBox> keep{{{-5, 0, 7}, {3, 9, 70000}}, {{1, 1, 1}, {1, 1, 1}}};
  for (const world::Edit& e : test::one_edit_of_each_kind()) {
    const auto bytes = encode_edit(e, keep);
    EXPECT_EQ(bytes[0], kClippedEditFormat);
    EXPECT_EQ(bytes.size(), encode_edit(e).size() + 2 + 2 * 24);
    std::string why;
    const auto back = decode_edit_record(bytes, &why);
    ASSERT_TRUE(back) << why;
    ASSERT_EQ(back->keep.size(), 2u);
    EXPECT_EQ(back->keep[0].lo, keep[0].lo);
    EXPECT_EQ(back->keep[0].hi, keep[0].hi);
    EXPECT_EQ(encode_edit(back->edit, back->keep), bytes) << describe_edit(e);
    for (size_t n = 0; n < bytes.size(); ++n)
      EXPECT_FALSE(decode_edit_record({bytes.data(), n})) << describe_edit(e) << " cut at " << n;
  }
  auto bytes = encode_edit(world::Explosion{}, keep);
  const size_t count_at = encode_edit(world::Explosion{}).size();
  auto zero = bytes;
  zero[count_at] = 0, zero[count_at + 1] = 0;
  EXPECT_FALSE(decode_edit_record(zero)) << "a clipped record without a box";
  auto inverted = bytes;
  inverted[count_at + 2 + 3] = 0x7f;  // box 0's min x becomes larger than its max
  EXPECT_FALSE(decode_edit_record(inverted));
  EXPECT_TRUE(decode_edit_record(encode_edit(world::Explosion{}))->keep.empty());
}

TEST(EditCodec, RefusesUnknownFormatsKindsAndFlags) {
  auto bytes = encode_edit(world::Brush{});
  auto bad = bytes;
  bad[0] = 2;
  EXPECT_FALSE(decode_edit(bad));
  bad = bytes;
  bad[1] = 5;
  EXPECT_FALSE(decode_edit(bad));
  bad = bytes;
  bad[bytes.size() - 2] = 4;  // brush flags
  EXPECT_FALSE(decode_edit(bad));
  auto stamp = encode_edit(world::Stamp{});
  stamp[2] = 2;  // shape
  EXPECT_FALSE(decode_edit(stamp));
}

TEST(EditCodec, RandomBytesNeverCrash) {
  std::mt19937 rng(5);
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> b(rng() % 40);
    for (auto& x : b) x = static_cast<uint8_t>(rng());
    if (!b.empty()) b[0] = kEditFormat;
    (void)decode_edit(b);
  }
}

TEST(ChunkCodec, TerrainAndUniformChunksRoundTripExactly) {
  const world::TerrainGenerator gen(3);
  size_t surface = 0;
  for (int y = -3; y <= 3; ++y) {
    const world::Chunk c = gen.generate({1, y, -2});
    const auto bytes = encode_chunk(c);
    std::string why;
    const auto back = decode_chunk(bytes, &why);
    ASSERT_TRUE(back) << why;
    EXPECT_TRUE(*back == c);
    EXPECT_EQ(back->is_uniform(), c.is_uniform());
    if (!c.is_uniform()) {
      ++surface;
      EXPECT_LT(bytes.size(), 98304u / 2) << "terrain compresses";
    } else {
      EXPECT_EQ(bytes.size(), 5u);
    }
  }
  EXPECT_GT(surface, 0u);
}

TEST(ChunkCodec, RefusesFramesThatDoNotDeclareExactlyAChunk) {
  world::Chunk c;
  c.set(1, 2, 3, {100, 2});
  auto bytes = encode_chunk(c);
  ASSERT_TRUE(decode_chunk(bytes));
  for (size_t n = 0; n < bytes.size(); ++n) EXPECT_FALSE(decode_chunk({bytes.data(), n})) << n;
  // A frame of another size, and one without a declared size.
  std::vector<uint8_t> small(1000, 1), frame(2 + ZSTD_compressBound(1000));
  frame[0] = kChunkFormat;
  frame[1] = 1;
  frame.resize(2 +
               ZSTD_compress(frame.data() + 2, frame.size() - 2, small.data(), small.size(), 1));
  std::string why;
  EXPECT_FALSE(decode_chunk(frame, &why));
  EXPECT_NE(why.find("size"), std::string::npos) << why;
  // A uniform record with a density below -32767.
  EXPECT_FALSE(decode_chunk(std::vector<uint8_t>{kChunkFormat, 0, 0x00, 0x80, 0}));
  EXPECT_FALSE(decode_chunk(std::vector<uint8_t>{kChunkFormat, 7, 0, 0, 0}));
}

TEST(ChunkCodec, RandomBytesNeverCrash) {
  std::mt19937 rng(9);
  const auto good = encode_chunk(world::TerrainGenerator(1).generate({0, 0, 0}));
  for (int i = 0; i < 2000; ++i) {
    auto b = good;
    for (int k = 0; k < 4; ++k) b[2 + rng() % (b.size() - 2)] = static_cast<uint8_t>(rng());
    (void)decode_chunk(b);
  }
}

}  // namespace
}  // namespace vox::store
