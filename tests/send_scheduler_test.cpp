#include <gtest/gtest.h>

// GCC 12 reports a false -Wstringop-overflow for Buffer::resize inlined into publish().
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#endif

#include <algorithm>
#include <map>

#include "server/net/send_scheduler.hpp"

namespace vox::net {
namespace {

using pipeline::MeshVersion;
using pipeline::MeshVersionPtr;
using world::ChunkCoord;

// A published store in miniature: coord -> newest version.
struct FakeStore {
  std::map<ChunkCoord, MeshVersionPtr> meshes;
  uint64_t next_version = 1;
  void publish(ChunkCoord c, bool empty = false) {
    auto v = std::make_shared<MeshVersion>();
    v->coord = c;
    v->version = next_version++;
    if (!empty) v->triangles = 1;
    meshes[c] = v;
  }
  SendScheduler::Lookup lookup() {
    return [this](ChunkCoord c) {
      auto it = meshes.find(c);
      return it == meshes.end() ? nullptr : it->second;
    };
  }
};

// A radius-1 view at the origin, every chunk of it published and sent.
SendScheduler fully_sent_radius_one_view(FakeStore& store) {
  for (ChunkCoord c :
       {ChunkCoord{0, 0, 0}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}})
    store.publish(c);
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  while (s.next(store.lookup())) {
  }
  return s;
}

int64_t d2(ChunkCoord a, ChunkCoord b) {
  const int64_t x = a.x - b.x, y = a.y - b.y, z = a.z - b.z;
  return x * x + y * y + z * z;
}

TEST(SendScheduler, SendsTheViewNearestFirst) {
  FakeStore store;
  for (int z = -3; z <= 3; ++z)
    for (int y = -3; y <= 3; ++y)
      for (int x = -3; x <= 3; ++x) store.publish({x, y, z});
  SendScheduler s;
  EXPECT_TRUE(s.set_view({0, 0, 0}, 2).empty());
  int64_t last = -1;
  size_t sent = 0;
  while (auto send = s.next(store.lookup())) {
    EXPECT_GE(d2(send->coord, {0, 0, 0}), last);
    EXPECT_LE(d2(send->coord, {0, 0, 0}), 4);
    EXPECT_FALSE(send->base) << "first copies are full";
    last = d2(send->coord, {0, 0, 0});
    ++sent;
  }
  EXPECT_EQ(sent, s.visible_count());
  EXPECT_EQ(sent, 33u);  // chunks within radius 2
}

TEST(SendScheduler, CoalescesToTheNewestVersionAndDeltasFromTheHeldOne) {
  FakeStore store;
  store.publish({0, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 0);
  auto first = s.next(store.lookup());
  ASSERT_TRUE(first);
  const uint64_t held = first->version->version;
  for (int i = 0; i < 5; ++i) {  // five changes before the client reads again
    store.publish({0, 0, 0});
    s.mark_stale({0, 0, 0});
  }
  auto second = s.next(store.lookup());
  ASSERT_TRUE(second);
  const ChunkCoord origin{0, 0, 0};
  EXPECT_EQ(second->version->version, store.meshes[origin]->version) << "only the newest is sent";
  ASSERT_TRUE(second->base);
  EXPECT_EQ(second->base->version, held);
  EXPECT_FALSE(s.next(store.lookup())) << "nothing older or duplicate follows";
  s.mark_stale({0, 0, 0});  // a stale mark without a newer version sends nothing
  EXPECT_FALSE(s.next(store.lookup()));
}

TEST(SendScheduler, EmptyFirstVersionIsNotSentButItsSuccessorIsSentInFull) {
  FakeStore store;
  for (int z = -1; z <= 1; ++z)
    for (int y = -1; y <= 1; ++y)
      for (int x = -1; x <= 1; ++x) store.publish({x, y, z}, true);
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  EXPECT_FALSE(s.next(store.lookup()));
  store.publish({1, 0, 0});
  s.mark_stale({1, 0, 0});
  auto send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_FALSE(send->base) << "the client never received the empty version";
}

TEST(SendScheduler, UnpublishedChunksWaitAndInvisibleOnesAreIgnored) {
  FakeStore store;
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  EXPECT_FALSE(s.next(store.lookup()));  // nothing published yet
  store.publish({0, 0, 0});
  store.publish({9, 9, 9});
  s.mark_stale({0, 0, 0});
  s.mark_stale({9, 9, 9});
  auto send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_EQ(send->coord, (ChunkCoord{0, 0, 0}));
  EXPECT_FALSE(s.next(store.lookup()));
}

// An outside client saw 51 cached chunks out to distance² 16 arrive before the centre of
// a view that partly overlapped the previous one: nearest first held only among chunks
// already loaded.
TEST(SendScheduler, NewChunksGoNearestFirstWhateverIsAlreadyLoaded) {
  FakeStore store;
  for (int x = 1; x <= 3; ++x) store.publish({x, 0, 0});  // loaded for an earlier view
  SendScheduler s;
  s.set_view({0, 0, 0}, 3);
  EXPECT_FALSE(s.next(store.lookup())) << "the centre is still loading";
  store.publish({0, 0, 0});
  s.mark_stale({0, 0, 0});
  std::vector<ChunkCoord> order;
  while (auto send = s.next(store.lookup())) order.push_back(send->coord);
  ASSERT_FALSE(order.empty());
  EXPECT_EQ(order.front(), (ChunkCoord{0, 0, 0}));
  // (1,0,0) at distance 1 came next; (2,0,0) waits for the unloaded chunks at distance 1.
  EXPECT_EQ(order, (std::vector<ChunkCoord>{{0, 0, 0}, {1, 0, 0}}));
  // Everything nearer than (2,0,0) finishes loading.
  for (int z = -2; z <= 2; ++z)
    for (int y = -2; y <= 2; ++y)
      for (int x = -2; x <= 2; ++x) {
        const ChunkCoord c{x, y, z};
        if (d2(c, {0, 0, 0}) >= 4 || store.meshes.count(c)) continue;
        store.publish(c);
        s.mark_stale(c);
      }
  int64_t last = 0;
  while (auto send = s.next(store.lookup())) {
    const int64_t d = d2(send->coord, {0, 0, 0});
    EXPECT_GE(d, last);
    last = d;
    if (send->coord == ChunkCoord{2, 0, 0}) break;
  }
  EXPECT_EQ(last, 4) << "(2,0,0) once nothing nearer is loading";
}

// Issue 18: an edit's change of a chunk the client holds waited behind the client's own
// new-view chunks, nearest first.
TEST(SendScheduler, ANewerVersionOfAHeldChunkGoesBeforeNewTerrain) {
  FakeStore store;
  store.publish({2, 0, 0});
  SendScheduler s;
  s.set_view({2, 0, 0}, 0);
  ASSERT_TRUE(s.next(store.lookup()));  // the client holds (2,0,0)
  s.set_view({0, 0, 0}, 2);             // walks: (2,0,0) is now at the edge
  for (int x = -1; x <= 1; ++x) store.publish({x, 0, 0});
  store.publish({2, 0, 0});  // an edit changed it
  for (int x = -1; x <= 2; ++x) s.mark_stale({x, 0, 0});
  auto send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_EQ(send->coord, (ChunkCoord{2, 0, 0}));
  EXPECT_TRUE(send->base) << "a delta";
  send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_EQ(send->coord, (ChunkCoord{0, 0, 0})) << "then new terrain, nearest first";
}

// Within each class the order stays nearest first: updates of held chunks, then new ones.
TEST(SendScheduler, UpdatesGoNearestFirstAmongThemselvesThenNewChunksNearestFirst) {
  FakeStore store;
  auto publish_ball = [&store](ChunkCoord centre, int r) {
    for (int z = -r; z <= r; ++z)
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x)
          if (x * x + y * y + z * z <= r * r && !store.meshes.count(centre.offset(x, y, z)))
            store.publish(centre.offset(x, y, z));
  };
  publish_ball({0, 0, 0}, 3);
  SendScheduler s;
  s.set_view({0, 0, 0}, 3);
  while (s.next(store.lookup())) {
  }
  // The player steps to (1,0,0): the far side is new terrain (all of it loaded), and edits
  // change the held (3,0,0) and (0,0,0) (now 2 and 1 chunks away).
  publish_ball({1, 0, 0}, 3);
  s.set_view({1, 0, 0}, 3);
  store.publish({3, 0, 0});
  store.publish({0, 0, 0});
  s.mark_stale({3, 0, 0});
  s.mark_stale({0, 0, 0});
  std::vector<ChunkCoord> order;
  while (auto send = s.next(store.lookup())) order.push_back(send->coord);
  ASSERT_GE(order.size(), 3u);
  EXPECT_EQ(order[0], (ChunkCoord{0, 0, 0}));
  EXPECT_EQ(order[1], (ChunkCoord{3, 0, 0}));
  int64_t last = 0;
  for (size_t i = 2; i < order.size(); ++i) {
    const int64_t d = d2(order[i], {1, 0, 0});
    EXPECT_GT(d2(order[i], {0, 0, 0}), 9) << "only new chunks after the updates";
    EXPECT_GE(d, last) << "new chunks nearest first";
    last = d;
  }
  EXPECT_EQ(d2(order[2], {1, 0, 0}), 5);  // (3,1,0) and its like: the nearest new ones
}

TEST(SendScheduler, MovingTheViewUnloadsHeldChunksThatLeftIt) {
  FakeStore store;
  for (int x = -2; x <= 6; ++x) store.publish({x, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  while (s.next(store.lookup())) {
  }
  const auto left = s.set_view({4, 0, 0}, 1);
  std::vector<ChunkCoord> sorted = left;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, (std::vector<ChunkCoord>{{-1, 0, 0}, {0, 0, 0}, {1, 0, 0}}));
  auto send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_EQ(send->coord, (ChunkCoord{4, 0, 0})) << "the new centre comes first";
}

// The session sent a chunk's newest version, published by the batch of the client's own
// edit, before that edit's EditResult: a client matching deltas to its edits then waited
// for a change it already had (seconds in the 500-player run).
TEST(SendScheduler, AVersionAtOrAboveTheLimitWaitsUntilReleased) {
  FakeStore store;
  store.publish({0, 0, 0});
  store.publish({1, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  while (s.next(store.lookup())) {
  }
  const uint64_t first_of_edit = store.next_version;  // the edit's batch publishes from here
  store.publish({0, 0, 0});
  s.mark_stale({0, 0, 0});
  s.mark_stale({1, 0, 0});  // nothing newer: skipped
  EXPECT_FALSE(s.next(store.lookup(), first_of_edit)) << "sent before the edit's result";
  EXPECT_EQ(s.deferred_count(), 1u);
  store.publish({0, 0, 0});  // changed again meanwhile: deferred once
  s.mark_stale({0, 0, 0});
  EXPECT_FALSE(s.next(store.lookup(), first_of_edit));
  EXPECT_EQ(s.deferred_count(), 1u);
  s.release_deferred();  // the result is queued
  auto send = s.next(store.lookup());
  ASSERT_TRUE(send);
  EXPECT_EQ(send->coord, (ChunkCoord{0, 0, 0}));
  EXPECT_EQ(send->version->version, store.meshes.at({0, 0, 0})->version);
  EXPECT_TRUE(send->base) << "a delta against what the client held";
  EXPECT_FALSE(s.next(store.lookup()));
}

TEST(SendScheduler, VersionsBelowTheLimitStillFlow) {
  FakeStore store;
  for (int z = -1; z <= 1; ++z)
    for (int y = -1; y <= 1; ++y)
      for (int x = -1; x <= 1; ++x)
        if (ChunkCoord{x, y, z} != ChunkCoord{1, 0, 0}) store.publish({x, y, z});
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  const uint64_t limit = store.next_version;
  store.publish({1, 0, 0});  // at the limit: may show the pending edit
  size_t sent = 0;
  while (s.next(store.lookup(), limit)) ++sent;
  EXPECT_EQ(sent, 6u) << "the centre and its other five neighbours";
  EXPECT_EQ(s.deferred_count(), 1u);
  s.set_view({0, 0, 0}, 1);  // a new view re-checks everything; nothing stays deferred
  EXPECT_EQ(s.deferred_count(), 0u);
}

// ViewReady: once per view, only when every visible chunk was sent or found empty.
TEST(SendScheduler, TheViewIsCompleteOnceEveryChunkIsSentOrEmptyAndOnlyOnce) {
  FakeStore store;
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);  // 7 chunks
  store.publish({0, 0, 0});
  store.publish({1, 0, 0}, /*empty=*/true);
  while (s.next(store.lookup())) {
  }
  EXPECT_FALSE(s.take_view_complete()) << "five chunks are not published yet";
  for (ChunkCoord c : {ChunkCoord{-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}}) {
    store.publish(c);
    s.mark_stale(c);
  }
  while (s.next(store.lookup())) {
  }
  EXPECT_FALSE(s.take_view_complete()) << "(0,0,-1) is still missing";
  store.publish({0, 0, -1}, true);
  s.mark_stale({0, 0, -1});
  EXPECT_FALSE(s.next(store.lookup()));
  const auto complete = s.take_view_complete();
  ASSERT_TRUE(complete);
  EXPECT_EQ(complete->sent, 5u);
  EXPECT_EQ(complete->empty, 2u);
  EXPECT_FALSE(s.take_view_complete()) << "once per view";
  store.publish({0, 0, 0});  // a change after the view is complete
  s.mark_stale({0, 0, 0});
  EXPECT_TRUE(s.next(store.lookup()));
  EXPECT_FALSE(s.take_view_complete());
  s.set_view({0, 0, 0}, 1);  // the same view again: complete again at once
  EXPECT_FALSE(s.next(store.lookup()));
  EXPECT_TRUE(s.take_view_complete());
}

TEST(SendScheduler, AMovedViewIsCompleteOnlyWhenItsNewChunksAreSent) {
  FakeStore store;
  for (int x = -1; x <= 2; ++x) store.publish({x, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 0);
  EXPECT_TRUE(s.next(store.lookup()));
  s.set_view({1, 0, 0}, 1);  // (1,0,0) and (2,0,0) published; (1,±1,0), (1,0,±1) not
  while (s.next(store.lookup())) {
  }
  EXPECT_FALSE(s.take_view_complete());
  s.set_view({1, 0, 0}, 0);  // shrunk to one chunk, already sent
  const auto complete = s.take_view_complete();
  ASSERT_TRUE(complete);
  EXPECT_EQ(complete->sent, 1u);
  EXPECT_EQ(complete->empty, 0u);
}

TEST(SendScheduler, AResyncedChunkGoesAgainInFullBeforeNewChunksEvenWhenEmpty) {
  FakeStore store;
  store.publish({0, 0, 0});
  store.publish({1, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 1);
  ASSERT_TRUE(s.next(store.lookup()));  // (0,0,0)
  ASSERT_TRUE(s.next(store.lookup()));  // (1,0,0)
  store.publish({1, 0, 0});
  s.mark_stale({1, 0, 0});
  EXPECT_TRUE(s.resync({1, 0, 0}));
  EXPECT_FALSE(s.resync({5, 0, 0})) << "not in the view";
  store.publish({0, 1, 0});  // new to the client, nearer than nothing: still after the resync
  s.mark_stale({0, 1, 0});
  auto again = s.next(store.lookup());
  ASSERT_TRUE(again);
  EXPECT_EQ(again->coord, (ChunkCoord{1, 0, 0}));
  EXPECT_FALSE(again->base) << "a resync is answered in full, never as a delta";
  EXPECT_EQ(again->version, store.lookup()(again->coord));
  auto fresh = s.next(store.lookup());
  ASSERT_TRUE(fresh);
  EXPECT_EQ(fresh->coord, (ChunkCoord{0, 1, 0}));
  // The next change after the resync is a delta against the full copy.
  store.publish({1, 0, 0});
  s.mark_stale({1, 0, 0});
  auto delta = s.next(store.lookup());
  ASSERT_TRUE(delta);
  ASSERT_TRUE(delta->base);
  EXPECT_EQ(delta->base->version, again->version->version);
  // An empty chunk is not sent to a new client, but is when it asks for it.
  store.publish({0, -1, 0}, true);
  s.mark_stale({0, -1, 0});
  EXPECT_FALSE(s.next(store.lookup()));
  EXPECT_TRUE(s.resync({0, -1, 0}));
  auto empty = s.next(store.lookup());
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->coord, (ChunkCoord{0, -1, 0}));
  EXPECT_EQ(empty->version->triangles, 0u);
}

TEST(SendScheduler, AResyncAskedTwiceBeforeItsCopyLeftIsSentOnce) {
  FakeStore store;
  store.publish({0, 0, 0});
  SendScheduler s;
  s.set_view({0, 0, 0}, 0);
  ASSERT_TRUE(s.next(store.lookup()));
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(s.resync({0, 0, 0}));
  EXPECT_EQ(s.stale_count(), 1u);
  EXPECT_TRUE(s.next(store.lookup()));
  EXPECT_FALSE(s.next(store.lookup()));
}

TEST(SendScheduler, TwoResyncsEachAnsweredAfterTheOtherGiveTwoCopies) {
  FakeStore store;
  SendScheduler s = fully_sent_radius_one_view(store);
  ASSERT_TRUE(s.take_view_complete());
  EXPECT_TRUE(s.resync({0, 0, 0}));
  EXPECT_TRUE(s.next(store.lookup()));
  EXPECT_TRUE(s.resync({0, 0, 0}));
  EXPECT_TRUE(s.next(store.lookup()));
  EXPECT_FALSE(s.next(store.lookup())) << "a third copy";
  EXPECT_FALSE(s.take_view_complete());
}

TEST(SendScheduler, AChunkResyncedAndThenUnloadedGetsNoChunkUnload) {
  FakeStore store;
  SendScheduler s = fully_sent_radius_one_view(store);
  EXPECT_TRUE(s.resync({1, 0, 0}));  // dropped by the client, its copy not sent yet
  const auto unloaded = s.set_view({-2, 0, 0}, 1);
  EXPECT_EQ(std::count(unloaded.begin(), unloaded.end(), ChunkCoord{1, 0, 0}), 0);
  EXPECT_EQ(std::count(unloaded.begin(), unloaded.end(), ChunkCoord{0, 0, 0}), 1);
}

}  // namespace
}  // namespace vox::net
