// What a session sends of its level-of-detail chunks (server/net/lod_send_queue.hpp).
#include "server/net/lod_send_queue.hpp"

#include <gtest/gtest.h>

#include <map>

namespace vox::net {
namespace {

using pipeline::LodKey;
using pipeline::MeshVersion;
using pipeline::MeshVersionPtr;
using world::LodChunk;
using world::LodSeams;

// Published meshes by key; a version with one triangle, or none.
struct Published {
  std::map<std::tuple<int, int, int, int, int, int>, MeshVersionPtr> meshes;
  uint64_t next = 1;
  static std::tuple<int, int, int, int, int, int> id(const LodKey& k) {
    return {k.chunk.level, k.chunk.c.x, k.chunk.c.y, k.chunk.c.z, k.seams.faces, k.seams.edges};
  }
  MeshVersionPtr publish(const LodKey& k, bool surface = true) {
    auto v = std::make_shared<MeshVersion>();
    v->coord = k.chunk.c;
    v->version = next++;
    v->triangles = surface ? 1 : 0;  // a level-of-detail version keeps no mesh
    meshes[id(k)] = v;
    return v;
  }
  LodSendQueue::Lookup lookup() const {
    return [this](const LodKey& k) {
      const auto it = meshes.find(id(k));
      return it == meshes.end() ? nullptr : it->second;
    };
  }
};

const std::array<double, 3> kEye{10, 10, 10};

world::LodViewChange sends(std::vector<std::pair<LodChunk, LodSeams>> s) {
  world::LodViewChange c;
  c.send = std::move(s);
  return c;
}

TEST(LodSendQueue, SendsNearestFirstAndWaitsForWhatIsNotMeshedYet) {
  LodSendQueue q;
  const LodChunk near{1, {1, 0, 0}}, far{2, {3, 0, 0}}, level0{0, {0, 0, 0}};
  q.apply(sends({{far, {}}, {near, {}}, {level0, {}}}), kEye);
  EXPECT_EQ(q.size(), 2u) << "level 0 is the SendScheduler's";
  Published p;
  EXPECT_FALSE(q.next(p.lookup())) << "nothing meshed";
  p.publish({far, {}});
  p.publish({near, {}});
  q.mark_stale({far, {}});
  q.mark_stale({near, {}});
  const auto first = q.next(p.lookup());
  ASSERT_TRUE(first);
  EXPECT_EQ(first->chunk, near);
  EXPECT_FALSE(first->base);
  const auto second = q.next(p.lookup());
  ASSERT_TRUE(second);
  EXPECT_EQ(second->chunk, far);
  EXPECT_GT(second->wire_version, first->wire_version);
  EXPECT_FALSE(q.next(p.lookup()));
}

TEST(LodSendQueue, AFirstVersionWithoutSurfaceIsResolvedButNotSentAndCompleteComesOnce) {
  LodSendQueue q;
  const LodChunk a{1, {0, 0, 0}}, b{1, {1, 0, 0}};
  Published p;
  p.publish({a, {}});
  p.publish({b, {}}, false);
  q.apply(sends({{a, {}}, {b, {}}}), kEye);
  EXPECT_FALSE(q.take_complete());
  ASSERT_TRUE(q.next(p.lookup()));
  EXPECT_FALSE(q.next(p.lookup())) << "the empty chunk is not sent";
  const auto done = q.take_complete();
  ASSERT_TRUE(done);
  EXPECT_EQ(done->sent, 1u);
  EXPECT_EQ(done->empty, 1u);
  EXPECT_FALSE(q.take_complete()) << "once per view";
  // The empty chunk gets a surface: sent in full; the held one loses it: sent, as a delta.
  p.publish({b, {}});
  q.mark_stale({b, {}});
  const auto full = q.next(p.lookup());
  ASSERT_TRUE(full);
  EXPECT_FALSE(full->base);
  p.publish({a, {}}, false);
  q.mark_stale({a, {}});
  const auto cleared = q.next(p.lookup());
  ASSERT_TRUE(cleared);
  EXPECT_TRUE(cleared->base);
  EXPECT_EQ(cleared->version->triangles, 0u);
}

TEST(LodSendQueue, NewSeamsSendTheOtherVariantAsADeltaWithARisingWireVersion) {
  LodSendQueue q;
  const LodChunk c{2, {0, 0, 0}};
  const LodSeams plain{}, seamed{1, 0};
  Published p;
  const MeshVersionPtr seamed_v = p.publish({c, world::normalized(seamed)});  // meshed first
  const MeshVersionPtr plain_v = p.publish({c, plain});
  q.apply(sends({{c, plain}}), kEye);
  const auto first = q.next(p.lookup());
  ASSERT_TRUE(first);
  EXPECT_EQ(first->version, plain_v);
  EXPECT_TRUE(q.take_complete());
  q.apply(sends({{c, seamed}}), kEye);
  EXPECT_FALSE(q.take_complete()) << "the client holds the old seams: not complete yet";
  ASSERT_EQ(q.wants().size(), 1u);
  EXPECT_EQ(q.wants()[0].seams, world::normalized(seamed));
  const auto second = q.next(p.lookup());
  ASSERT_TRUE(second);
  EXPECT_EQ(second->version, seamed_v) << "its server version is older";
  EXPECT_EQ(second->base, plain_v);
  EXPECT_EQ(second->wire_base, first->wire_version);
  EXPECT_GT(second->wire_version, first->wire_version) << "what the client sees still rises";
  EXPECT_TRUE(q.take_complete());
  // A publication of the variant the client no longer needs is ignored.
  p.publish({c, plain});
  q.mark_stale({c, plain});
  EXPECT_FALSE(q.next(p.lookup()));
}

TEST(LodSendQueue, UnloadListsOnlyWhatWasSentAndResyncSendsInFull) {
  LodSendQueue q;
  const LodChunk sent{1, {0, 0, 0}}, never{1, {5, 0, 0}};
  Published p;
  p.publish({sent, {}});
  q.apply(sends({{sent, {}}, {never, {}}}), kEye);
  const auto s = q.next(p.lookup());
  ASSERT_TRUE(s);
  EXPECT_TRUE(q.resync(sent));
  EXPECT_FALSE(q.resync({1, {9, 9, 9}}));
  const auto again = q.next(p.lookup());
  ASSERT_TRUE(again);
  EXPECT_FALSE(again->base) << "a resync goes in full";
  world::LodViewChange gone;
  gone.unload = {sent, never};
  const auto unloaded = q.apply(gone, kEye);
  ASSERT_EQ(unloaded.size(), 1u);
  EXPECT_EQ(unloaded[0], sent);
  EXPECT_EQ(q.size(), 0u);
  EXPECT_TRUE(q.complete());
}

// A walking player's SetViews mostly leave the layout as it was: an empty change then
// re-orders what is queued at the new distances and queues nothing else, and the view is
// complete again once that is sent.
TEST(LodSendQueue, AnUnchangedLayoutReordersTheQueuedChunksAndQueuesNothingElse) {
  LodSendQueue q;
  const LodChunk a{1, {1, 0, 0}}, b{1, {-2, 0, 0}}, held{1, {0, 3, 0}};
  Published p;
  q.apply(sends({{a, {}}, {b, {}}, {held, {}}}), kEye);
  p.publish({held, {}});
  q.mark_stale({held, {}});
  ASSERT_TRUE(q.next(p.lookup()));
  ASSERT_TRUE(q.take_complete() == std::nullopt);
  p.publish({a, {}});
  p.publish({b, {}});
  q.mark_stale({a, {}});
  q.mark_stale({b, {}});
  q.apply({}, {-60, 10, 10});  // the eye moved next to b
  const auto first = q.next(p.lookup());
  ASSERT_TRUE(first);
  EXPECT_EQ(first->chunk, b) << "re-ordered at the new distances";
  const auto second = q.next(p.lookup());
  ASSERT_TRUE(second);
  EXPECT_EQ(second->chunk, a);
  EXPECT_FALSE(q.next(p.lookup())) << "the held chunk is not sent again";
  const auto complete = q.take_complete();
  ASSERT_TRUE(complete);
  EXPECT_EQ(complete->sent, 3u);
  q.apply({}, kEye);
  EXPECT_FALSE(q.next(p.lookup()));
  EXPECT_TRUE(q.take_complete()) << "each view is announced complete";
}

// A chunk looked at before its mesh existed waits for mark_stale(); an unchanged layout in
// between must not lose it.
TEST(LodSendQueue, AChunkNotMeshedYetIsSentWhenPublishedAfterAnUnchangedLayout) {
  LodSendQueue q;
  const LodChunk c{2, {1, 0, 0}};
  Published p;
  q.apply(sends({{c, {}}}), kEye);
  EXPECT_FALSE(q.next(p.lookup())) << "not meshed yet";
  q.apply({}, {12, 10, 10});
  EXPECT_FALSE(q.next(p.lookup()));
  EXPECT_FALSE(q.take_complete());
  p.publish({c, {}});
  q.mark_stale({c, {}});
  const auto sent = q.next(p.lookup());
  ASSERT_TRUE(sent);
  EXPECT_EQ(sent->chunk, c);
  EXPECT_TRUE(q.take_complete());
}

}  // namespace
}  // namespace vox::net
