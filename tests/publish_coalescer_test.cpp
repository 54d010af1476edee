#include "server/net/publish_coalescer.hpp"

#include <gtest/gtest.h>

namespace vox::net {
namespace {

using world::ChunkCoord;
using Chunks = std::vector<ChunkCoord>;

TEST(PublishCoalescer, APublicationGoesAtOnceWhenNoFanOutIsInFlight) {
  PublishCoalescer c;
  EXPECT_TRUE(c.add({{1, 0, 0}}));
  EXPECT_EQ(c.take(), (Chunks{{1, 0, 0}}));
  EXPECT_FALSE(c.handled());  // nothing gathered meanwhile
  EXPECT_FALSE(c.in_flight());
  EXPECT_TRUE(c.add({{2, 0, 0}}));
  EXPECT_EQ(c.take(), (Chunks{{2, 0, 0}}));
}

TEST(PublishCoalescer, PublicationsWhileAFanOutIsUnhandledGoTogetherEachChunkOnceWhenItIs) {
  PublishCoalescer c;
  ASSERT_TRUE(c.add({{1, 0, 0}}));
  c.take();
  EXPECT_FALSE(c.add({{3, 0, 0}, {2, 0, 0}}));
  EXPECT_FALSE(c.add({{2, 0, 0}}));
  EXPECT_EQ(c.pending(), 3u);
  EXPECT_TRUE(c.handled());
  EXPECT_TRUE(c.in_flight());
  EXPECT_EQ(c.take(), (Chunks{{2, 0, 0}, {3, 0, 0}}));
  // That second fan-out is in flight now: the next publication waits for it.
  EXPECT_FALSE(c.add({{4, 0, 0}}));
  EXPECT_TRUE(c.handled());
  EXPECT_EQ(c.take(), (Chunks{{4, 0, 0}}));
  EXPECT_FALSE(c.handled());
  EXPECT_FALSE(c.in_flight());
}

TEST(PublishCoalescer, TheGatheredListStaysWithinTheDistinctChunksWhileAFanOutIsNeverHandled) {
  PublishCoalescer c;
  ASSERT_TRUE(c.add({{0, 0, 0}}));
  c.take();
  Chunks batch;
  for (int i = 0; i < 100; ++i) batch.push_back({i, 0, 0});
  for (int round = 0; round < 1000; ++round) EXPECT_FALSE(c.add(batch));
  EXPECT_LE(c.pending(), 4096u + batch.size());
  ASSERT_TRUE(c.handled());
  EXPECT_EQ(c.take(), batch);
}

}  // namespace
}  // namespace vox::net
