// What a session's client sees (server/net/view_feed.hpp), driven with no socket and no
// session: real mesh stores, the pipeline's wants recorded.
#include "server/net/view_feed.hpp"

#include <gtest/gtest.h>

// GCC 12 reports a false -Wstringop-overflow for ChunkMesh's buffer resizes inlined here.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#endif

#include <algorithm>
#include <set>

#include "server/net/wire_convert.hpp"
#include "tests/alloc_counter.hpp"

namespace vox::net {
namespace {

using pipeline::LodKey;
using pipeline::MeshVersion;
using pipeline::MeshVersionPtr;
using world::ChunkCoord;

int64_t d2(ChunkCoord a, ChunkCoord b) {
  const int64_t x = a.x - b.x, y = a.y - b.y, z = a.z - b.z;
  return x * x + y * y + z * z;
}

// A feed over its own stores, with what it asked of the pipeline.
struct Fixture {
  pipeline::MeshStore meshes;
  pipeline::LodMeshStore lod_meshes;
  ServerCounters counters;
  uint64_t next_version = 1;
  struct {
    ChunkCoord center{};
    int radius = -1;
    SendScheduler::Keep keep;
    std::optional<std::vector<LodKey>> lod;  // the last set_lod_view
  } wanted;
  ViewFeed feed{meshes,
                lod_meshes,
                {.set_view =
                     [this](ChunkCoord center, int radius, const SendScheduler::Keep& keep) {
                       wanted.center = center;
                       wanted.radius = radius;
                       wanted.keep = keep;
                     },
                 .set_lod_view = [this](std::vector<LodKey> keys) { wanted.lod = keys; }},
                counters};

  MeshVersionPtr version(ChunkCoord c, bool surface, size_t bytes = 16) {
    auto v = std::make_shared<MeshVersion>();
    v->coord = c;
    v->version = next_version++;
    if (surface) v->triangles = 1;
    v->encoding.assign(bytes, static_cast<uint8_t>(v->version));
    v->full_frame.assign(bytes, static_cast<uint8_t>(v->version));
    return v;
  }
  void publish(const std::vector<ChunkCoord>& chunks, bool surface = true) {
    for (const ChunkCoord c : chunks) meshes.publish(version(c, surface));
    feed.chunks_published(chunks);
  }
  void publish_lod(const std::vector<LodKey>& keys) {
    for (const LodKey& k : keys) lod_meshes.publish(k, version(k.chunk.c, true));
    feed.lod_published(keys);
  }
  // Every mesh the feed has now, in order (one write after another).
  std::vector<wire::ChunkMesh> drain() {
    std::vector<wire::ChunkMesh> out;
    feed.begin_write();
    while (const wire::Envelope* m = feed.next_mesh(UINT64_MAX)) out.push_back(m->chunk_mesh());
    return out;
  }
  // The chunks of the ball the pipeline was asked to load (those `keep` lets through).
  std::vector<ChunkCoord> wanted_chunks() const {
    std::vector<ChunkCoord> out;
    const int r = wanted.radius;
    for (int z = -r; z <= r; ++z)
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
          const ChunkCoord c{wanted.center.x + x, wanted.center.y + y, wanted.center.z + z};
          if (d2(c, wanted.center) <= int64_t{r} * r && (!wanted.keep || wanted.keep(c)))
            out.push_back(c);
        }
    return out;
  }
};

ViewFeed::View view(ChunkCoord center, int radius, uint64_t id) {
  ViewFeed::View v;
  v.center = center;
  v.radius = radius;
  v.view_id = id;
  v.eye = {center.x * 32.0 + 16, center.y * 32.0 + 16, center.z * 32.0 + 16};
  return v;
}

TEST(ViewFeed, AViewsChunksComeNearestFirstOnceTheyArePublished) {
  Fixture f;
  EXPECT_TRUE(f.feed.apply_view(view({0, 0, 0}, 2, 1)).empty());
  EXPECT_EQ(f.wanted.radius, 2) << "the pipeline is asked for the view";
  EXPECT_FALSE(f.wanted.keep);
  EXPECT_TRUE(f.drain().empty()) << "nothing published yet";
  std::vector<ChunkCoord> chunks = f.wanted_chunks();
  std::reverse(chunks.begin(), chunks.end());
  f.publish(chunks);
  const auto sent = f.drain();
  ASSERT_EQ(sent.size(), chunks.size());
  int64_t last = -1;
  for (const wire::ChunkMesh& m : sent) {
    EXPECT_GE(d2(from_wire(m.coord()), {0, 0, 0}), last);
    last = d2(from_wire(m.coord()), {0, 0, 0});
    EXPECT_EQ(m.base_version(), 0u) << "first copies are full";
    EXPECT_EQ(m.level(), 0u);
  }
  EXPECT_EQ(f.counters.meshes_sent.load(), chunks.size());
}

TEST(ViewFeed, AHeldChunksNewVersionGoesAsADeltaFromWhatTheClientHolds) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 0, 1));
  f.publish({{0, 0, 0}});
  const auto first = f.drain();
  ASSERT_EQ(first.size(), 1u);
  f.publish({{0, 0, 0}});
  const auto update = f.drain();
  ASSERT_EQ(update.size(), 1u);
  EXPECT_EQ(update[0].base_version(), first[0].version());
  EXPECT_GT(update[0].version(), first[0].version());
  EXPECT_EQ(f.counters.deltas_sent.load(), 1u);
}

TEST(ViewFeed, MaySeeAnswersForChunksInTheViewOnlyAndNothingBeforeAView) {
  Fixture f;
  EXPECT_FALSE(f.feed.may_see({{0, 0, 0}})) << "no view yet";
  f.feed.apply_view(view({10, 0, 0}, 2, 1));
  EXPECT_TRUE(f.feed.may_see({{10, 0, 0}}));
  EXPECT_TRUE(f.feed.may_see({{12, 0, 0}})) << "on the ball's surface";
  EXPECT_FALSE(f.feed.may_see({{12, 1, 0}})) << "a corner outside the ball";
  EXPECT_FALSE(f.feed.may_see({{0, 0, 0}, {13, 0, 0}}));
  EXPECT_TRUE(f.feed.may_see({{0, 0, 0}, {11, 1, 0}})) << "one of them is enough";
  f.feed.apply_view(view({0, 0, 0}, 1, 2));
  EXPECT_FALSE(f.feed.may_see({{10, 0, 0}})) << "the new view replaced it";
}

TEST(ViewFeed, ViewReadyComesOnceAfterEveryChunkOfTheViewWasSentOrFoundEmpty) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 1, 7));
  std::vector<ChunkCoord> chunks = f.wanted_chunks();
  ASSERT_EQ(chunks.size(), 7u);
  const ChunkCoord last = chunks.back();
  chunks.pop_back();
  f.publish({chunks.front()}, false);  // no surface: found empty, not sent
  f.publish(std::vector<ChunkCoord>(chunks.begin() + 1, chunks.end()));
  EXPECT_EQ(f.drain().size(), 5u);
  wire::Envelope ready;
  EXPECT_FALSE(f.feed.take_view_ready(ready)) << "one chunk is still loading";
  f.publish({last});
  EXPECT_EQ(f.drain().size(), 1u);
  ASSERT_TRUE(f.feed.take_view_ready(ready));
  EXPECT_EQ(ready.view_ready().view_id(), 7u);
  EXPECT_EQ(ready.view_ready().radius(), 1u);
  EXPECT_EQ(ready.view_ready().chunks_sent(), 6u);
  EXPECT_EQ(ready.view_ready().chunks_empty(), 1u);
  EXPECT_EQ(from_wire(ready.view_ready().center()), (ChunkCoord{0, 0, 0}));
  wire::Envelope again;
  EXPECT_FALSE(f.feed.take_view_ready(again)) << "once per view";
  f.publish({last});
  EXPECT_EQ(f.drain().size(), 1u);
  EXPECT_FALSE(f.feed.take_view_ready(again)) << "an update is no new view";
}

TEST(ViewFeed, ANewViewReplacesTheOldOneItsUnloadsFirstAndItsIdInItsViewReady) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 1, 1));
  const std::vector<ChunkCoord> old_chunks = f.wanted_chunks();
  f.publish(old_chunks);
  EXPECT_EQ(f.drain().size(), 7u);  // its ViewReady not taken yet
  const auto unloads = f.feed.apply_view(view({1, 0, 0}, 1, 2));
  ASSERT_EQ(unloads.size(), 1u);
  std::set<ChunkCoord> gone;
  for (const auto& c : unloads[0].chunk_unload().coords()) gone.insert(from_wire(c));
  EXPECT_EQ(unloads[0].chunk_unload().level(), 0u);
  // What left the radius-1 ball when its center moved one chunk along x.
  EXPECT_EQ(gone, (std::set<ChunkCoord>{{-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}}));
  wire::Envelope ready;
  EXPECT_FALSE(f.feed.take_view_ready(ready)) << "the old view's completion is not the new one's";
  f.publish({{2, 0, 0}, {1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1}});
  EXPECT_EQ(f.drain().size(), 5u) << "the two chunks the client holds are not sent again";
  ASSERT_TRUE(f.feed.take_view_ready(ready));
  EXPECT_EQ(ready.view_ready().view_id(), 2u);
  EXPECT_EQ(from_wire(ready.view_ready().center()), (ChunkCoord{1, 0, 0}));
}

// A level-1 LOD view around the origin, its level-0 chunks published and sent.
void lod_view_with_level0_sent(Fixture& f) {
  ViewFeed::View v = view({0, 0, 0}, 2, 3);
  v.lod_level = 1;
  v.lod_distance = 1.5;
  f.feed.apply_view(v);
  ASSERT_TRUE(f.feed.has_lod_view());
  ASSERT_TRUE(f.wanted.keep) << "level 0 is the layout's";
  ASSERT_TRUE(f.wanted.lod && !f.wanted.lod->empty());
  ASSERT_FALSE(f.wanted_chunks().empty());
  f.publish(f.wanted_chunks());
  const auto level0 = f.drain();
  ASSERT_EQ(level0.size(), f.wanted_chunks().size());
  for (const auto& m : level0) EXPECT_EQ(m.level(), 0u);
}

TEST(ViewFeed, ALodViewIsReadyOnlyOnceItsLevel0AndCoarserPartsAreBothSent) {
  Fixture f;
  lod_view_with_level0_sent(f);
  wire::Envelope ready;
  EXPECT_FALSE(f.feed.take_view_ready(ready)) << "the coarser chunks are not sent yet";
  f.publish_lod(*f.wanted.lod);
  const auto coarse = f.drain();
  ASSERT_EQ(coarse.size(), f.wanted.lod->size());
  for (const auto& m : coarse) EXPECT_GE(m.level(), 1u);
  ASSERT_TRUE(f.feed.take_view_ready(ready));
  EXPECT_EQ(ready.view_ready().view_id(), 3u);
  EXPECT_EQ(ready.view_ready().lod_chunks_sent(), coarse.size());
  EXPECT_EQ(ready.view_ready().chunks_sent(), f.wanted_chunks().size());
}

TEST(ViewFeed, CoarserMeshesWaitForEveryLevel0MeshDue) {
  Fixture f;
  ViewFeed::View v = view({0, 0, 0}, 2, 3);
  v.lod_level = 1;
  f.feed.apply_view(v);
  ASSERT_TRUE(f.wanted.lod);
  f.publish_lod(*f.wanted.lod);
  f.publish(f.wanted_chunks());
  const auto sent = f.drain();
  ASSERT_EQ(sent.size(), f.wanted_chunks().size() + f.wanted.lod->size());
  for (size_t i = 0; i < sent.size(); ++i)
    EXPECT_EQ(sent[i].level() == 0, i < f.wanted_chunks().size()) << i;
}

TEST(ViewFeed, DroppingALodViewUnloadsTheCoarserChunksTheClientHolds) {
  Fixture f;
  lod_view_with_level0_sent(f);
  f.publish_lod(*f.wanted.lod);
  const size_t held = f.drain().size();
  const auto unloads = f.feed.apply_view(view({0, 0, 0}, 2, 4));  // level 0 only
  EXPECT_FALSE(f.feed.has_lod_view());
  ASSERT_TRUE(f.wanted.lod);
  EXPECT_TRUE(f.wanted.lod->empty()) << "the pipeline's LOD wants are dropped";
  size_t unloaded = 0;
  for (const auto& u : unloads)
    if (u.chunk_unload().level() >= 1) unloaded += u.chunk_unload().coords_size();
  EXPECT_EQ(unloaded, held);
  EXPECT_FALSE(f.feed.lod_published(*f.wanted.lod)) << "no LOD view to feed";
}

TEST(ViewFeed, ResyncSendsAHeldChunkAgainInFullAndIgnoresOneOutsideTheView) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 0, 1));
  f.publish({{0, 0, 0}});
  ASSERT_EQ(f.drain().size(), 1u);
  EXPECT_FALSE(f.feed.resync(0, {5, 0, 0}));
  EXPECT_TRUE(f.feed.resync(0, {0, 0, 0}));
  const auto again = f.drain();
  ASSERT_EQ(again.size(), 1u);
  EXPECT_EQ(again[0].base_version(), 0u);
}

TEST(ViewFeed, MeshMessagesOnceWarmAllocateNothing) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 2, 1));
  f.publish(f.wanted_chunks());
  f.feed.begin_write();
  ASSERT_TRUE(f.feed.next_mesh(UINT64_MAX));  // warms the reused message
  const size_t before = test::allocations_on_this_thread();
  size_t sent = 1;
  while (f.feed.next_mesh(UINT64_MAX)) ++sent;
  EXPECT_EQ(test::allocations_on_this_thread() - before, 0u);
  EXPECT_EQ(sent, f.wanted_chunks().size());
}

TEST(ViewFeed, AVersionThatMayShowAnUnansweredEditWaitsUntilReleased) {
  Fixture f;
  f.feed.apply_view(view({0, 0, 0}, 0, 1));
  f.publish({{0, 0, 0}});
  const uint64_t limit = f.next_version - 1;  // the version just published
  f.feed.begin_write();
  EXPECT_FALSE(f.feed.next_mesh(limit));
  EXPECT_TRUE(f.feed.release_deferred());
  EXPECT_FALSE(f.feed.release_deferred()) << "nothing deferred any more";
  f.feed.begin_write();
  EXPECT_TRUE(f.feed.next_mesh(UINT64_MAX));
}

TEST(ViewFeed, ClearForgetsTheViewAndWhatTheClientHolds) {
  Fixture f;
  ViewFeed::View v = view({0, 0, 0}, 1, 1);
  v.lod_level = 1;
  f.feed.apply_view(v);
  f.publish(f.wanted_chunks());
  f.drain();
  EXPECT_GT(f.feed.memory_bytes(), 0u);
  f.feed.clear();
  EXPECT_FALSE(f.feed.has_view());
  EXPECT_FALSE(f.feed.has_lod_view());
  EXPECT_EQ(f.feed.memory_bytes(), 0u);
  EXPECT_FALSE(f.feed.chunks_published({{0, 0, 0}}));
}

}  // namespace
}  // namespace vox::net
