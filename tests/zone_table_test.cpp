// A cluster node's zones as its world sees them (server/cluster/zone_table.hpp): which
// zones' changed chunks may leave memory, what a loss after one did makes of the zone, and
// the order zones catch up in.
#include "server/cluster/zone_table.hpp"

#include <gtest/gtest.h>

namespace vox::cluster {
namespace {

using world::ZoneId;

// A changed chunk may be evicted only while its zone is held here and caught up: it is read
// back from the zone's checkpoint, which only this holder moves meanwhile.
TEST(ZoneTable, AZonesChangedChunksMayBeEvictedOnlyWhileItIsHeldAndCaughtUp) {
  ZoneTable t;
  const ZoneId zone{1, 2};
  EXPECT_FALSE(t.may_evict(zone));  // never held
  t.taken(zone, 7);
  EXPECT_FALSE(t.may_evict(zone));  // catching up
  t.caught_up(zone, 7, 40, true);
  EXPECT_TRUE(t.may_evict(zone));
  t.leave(zone, 7);
  EXPECT_FALSE(t.may_evict(zone));  // being handed off
  t.lost(zone, 7);
  EXPECT_FALSE(t.may_evict(zone));
}

// A zone lost after one of its chunks was evicted is installed afresh: a chunk read back
// from a later holder's checkpoint could be ahead of what this world has.
TEST(ZoneTable, AZoneLostAfterAChunkOfItWasEvictedIsInstalledAfresh) {
  ZoneTable t;
  const ZoneId kept{0, 0}, evicted{0, 1};
  for (const ZoneId z : {kept, evicted}) {
    t.taken(z, 3);
    t.caught_up(z, 3, 10, true);
    t.committed(z, 12);
  }
  ASSERT_TRUE(t.may_evict(evicted));
  t.lost(kept, 3);
  t.lost(evicted, 3);
  EXPECT_EQ(t.position(kept).applied, 12u);  // followed on from where it is
  EXPECT_FALSE(t.position(kept).fresh);
  EXPECT_EQ(t.applied(evicted), 0u);
  EXPECT_TRUE(t.position(evicted).fresh);
  EXPECT_EQ(t.next_fresh(), evicted);  // forgotten, or installed afresh if followed
  t.committed(evicted, 13);            // a late append's record: read from the log again
  EXPECT_EQ(t.applied(evicted), 0u);
  // Taken again while fresh: the pipeline forgets what it had first, then it catches up
  // from nothing, and only then is it writable.
  t.taken(evicted, 5);
  EXPECT_EQ(t.next_fresh(), evicted);
  EXPECT_FALSE(t.next_catch_up());
  t.caught_up(evicted, 5, 13, true);
  EXPECT_FALSE(t.writable(evicted));
  t.reset(evicted, 0);
  EXPECT_FALSE(t.next_fresh());
  const auto c = t.next_catch_up();
  ASSERT_TRUE(c);
  EXPECT_EQ(c->zone, evicted);
  EXPECT_EQ(c->applied, 0u);
  t.caught_up(evicted, 5, 13, true);
  EXPECT_EQ(t.writable(evicted), 5u);
  EXPECT_EQ(t.position(evicted).applied, 13u);
  EXPECT_FALSE(t.position(evicted).fresh);
  // A loss with nothing evicted since is not fresh again.
  t.lost(evicted, 5);
  EXPECT_FALSE(t.position(evicted).fresh);
}

// Zones catching up take turns: a zone whose log cannot be read or applied now (a damaged
// record, its turn ending in an error) holds up no other. (The first zone in order was
// asked for every time, and one that kept failing held up every zone taken after it.)
TEST(ZoneTable, ZonesCatchingUpTakeTurnsSoThatOneThatKeepsFailingHoldsUpNoOther) {
  ZoneTable t;
  const ZoneId first{0, 0}, second{0, 1}, third{2, 0};
  for (const ZoneId z : {first, second, third}) t.taken(z, 1);
  EXPECT_EQ(t.next_catch_up()->zone, first);
  EXPECT_EQ(t.next_catch_up(first)->zone, second);
  EXPECT_EQ(t.next_catch_up(second)->zone, third);
  EXPECT_EQ(t.next_catch_up(third)->zone, first);  // around
  t.caught_up(second, 1, 5, true);
  EXPECT_EQ(t.next_catch_up(first)->zone, third);  // the next still behind
  t.caught_up(first, 1, 5, true);
  t.caught_up(third, 1, 5, true);
  EXPECT_FALSE(t.next_catch_up(third).has_value());
  EXPECT_FALSE(t.next_catch_up().has_value());
}

}  // namespace
}  // namespace vox::cluster
