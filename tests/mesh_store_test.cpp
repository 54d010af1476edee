#include "server/pipeline/mesh_store.hpp"

#include <gtest/gtest.h>

#include <latch>
#include <random>
#include <thread>
#include <vector>

#include "proto/zstd_codec.hpp"

namespace vox::pipeline {
namespace {

std::shared_ptr<MeshVersion> version_with(uint64_t version, size_t encoding_bytes, uint8_t fill) {
  auto v = std::make_shared<MeshVersion>();
  v->coord = {1, 2, 3};
  v->version = version;
  v->encoding.assign(encoding_bytes, fill);
  for (size_t i = 0; i < encoding_bytes; i += 7)
    v->encoding[i] = static_cast<uint8_t>(i * 31 + version);
  return v;
}

// The delta caches were outside the memory budget: up to 8 deltas per version, also of
// versions replaced in the store that sessions still hold.
TEST(MeshStore, CachedDeltasCountInItsMemoryUntilTheirVersionIsGone) {
  MeshStore store;
  std::shared_ptr<MeshVersion> first = version_with(1, 4000, 1);
  store.publish(first);
  std::shared_ptr<MeshVersion> second = version_with(2, 4000, 2);
  store.publish(second);
  const size_t before = store.memory_bytes();
  const auto delta = second->delta_from(*first);
  ASSERT_GT(delta->capacity(), 0u);
  EXPECT_EQ(store.memory_bytes(), before + delta->capacity());
  EXPECT_EQ(second->delta_from(*first), delta) << "made once, then shared";
  EXPECT_EQ(store.memory_bytes(), before + delta->capacity());
  store.erase({1, 2, 3});
  EXPECT_EQ(store.memory_bytes(), delta->capacity()) << "a session still holds the version";
  second.reset();
  EXPECT_EQ(store.memory_bytes(), 0u);
}

TEST(MeshStore, AVersionKeepsAtMostEightDeltasInItsAccount) {
  MeshStore store;
  std::vector<std::shared_ptr<MeshVersion>> bases;
  for (uint64_t v = 1; v <= 12; ++v)
    bases.push_back(version_with(v, 3000, static_cast<uint8_t>(v)));
  std::shared_ptr<MeshVersion> newest = version_with(13, 3000, 13);
  store.publish(newest);
  const size_t published = store.memory_bytes();
  size_t last_eight = 0;
  std::vector<size_t> sizes;
  for (const auto& b : bases) sizes.push_back(newest->delta_from(*b)->capacity());
  for (size_t i = sizes.size() - 8; i < sizes.size(); ++i) last_eight += sizes[i];
  EXPECT_EQ(store.memory_bytes(), published + last_eight);
}

// A chunk's versions as a client sees them: random bytes (so a delta can only be small by
// referring to its base), each version a few bytes changed from the one before.
std::vector<std::shared_ptr<MeshVersion>> chain_of_versions(size_t count, size_t bytes) {
  std::mt19937 rng(5);
  std::vector<std::shared_ptr<MeshVersion>> chain;
  std::vector<uint8_t> encoding(bytes);
  for (auto& b : encoding) b = static_cast<uint8_t>(rng());
  for (uint64_t v = 1; v <= count; ++v) {
    for (int i = 0; i < 16; ++i) encoding[rng() % bytes] = static_cast<uint8_t>(rng());
    auto version = std::make_shared<MeshVersion>();
    version->coord = {1, 2, 3};
    version->version = v;
    version->encoding = encoding;
    chain.push_back(version);
  }
  return chain;
}

proto::Result<std::vector<uint8_t>> expand(const std::vector<uint8_t>& delta,
                                           const MeshVersion& base) {
  thread_local proto::ZstdCodec zstd;
  return zstd.decompress(delta, base.encoding, 1 << 20);
}

TEST(MeshVersionDelta, RebuildsTheNewEncodingFromItsBaseAndIsSmall) {
  const auto chain = chain_of_versions(3, 20000);
  for (size_t base = 0; base < 2; ++base) {
    const auto delta = chain[2]->delta_from(*chain[base]);
    auto rebuilt = expand(*delta, *chain[base]);
    ASSERT_TRUE(rebuilt) << rebuilt.error();
    EXPECT_TRUE(*rebuilt == chain[2]->encoding) << "base " << base;
    EXPECT_LT(delta->size(), 1000u) << "the delta refers to its base";
  }
}

// A client that holds another version than the delta's base cannot rebuild the encoding
// (the client detects it by the encoding's CRC, or the frame fails).
TEST(MeshVersionDelta, AgainstAnotherBaseDoesNotRebuildTheEncoding) {
  const auto chain = chain_of_versions(3, 20000);
  const auto delta = chain[2]->delta_from(*chain[1]);
  auto wrong = expand(*delta, *chain[0]);
  EXPECT_TRUE(!wrong || *wrong != chain[2]->encoding);
  MeshVersion empty_base;
  auto none = expand(*delta, empty_base);
  EXPECT_TRUE(!none || *none != chain[2]->encoding) << "decoded without its base";
}

// Empty encodings at either end (a base the client never had, a version with no bytes).
TEST(MeshVersionDelta, EmptyBaseOrEmptyEncodingRoundTrips) {
  const auto chain = chain_of_versions(1, 5000);
  MeshVersion empty;
  empty.version = 7;
  const auto from_empty = chain[0]->delta_from(empty);
  auto full = expand(*from_empty, empty);
  ASSERT_TRUE(full) << full.error();
  EXPECT_TRUE(*full == chain[0]->encoding);
  const auto to_empty = empty.delta_from(*chain[0]);
  auto nothing = expand(*to_empty, *chain[0]);
  ASSERT_TRUE(nothing) << nothing.error();
  EXPECT_TRUE(nothing->empty());
}

// Concurrent first requests for one base: each may compress, but all get one shared delta
// and the store counts it once.
TEST(MeshVersionDelta, ConcurrentRequestsForOneBaseShareOneDelta) {
  MeshStore store;
  const auto chain = chain_of_versions(2, 1 << 19);  // compressing takes a while
  store.publish(chain[1]);
  const size_t published = store.memory_bytes();
  constexpr int kThreads = 8;
  std::latch start(kThreads);
  std::vector<std::shared_ptr<const std::vector<uint8_t>>> got(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      start.arrive_and_wait();
      got[t] = chain[1]->delta_from(*chain[0]);
    });
  }
  for (auto& t : threads) t.join();
  for (int t = 1; t < kThreads; ++t) EXPECT_EQ(got[t].get(), got[0].get()) << "thread " << t;
  EXPECT_EQ(store.memory_bytes(), published + got[0]->capacity());
}

// Only the 8 most recent bases keep their delta (first in, first out): an older base gets
// a fresh one made, which still rebuilds the encoding, and pushes out the oldest in turn.
TEST(MeshVersionDelta, ABaseEvictedFromTheCacheGetsAFreshDeltaThatStillApplies) {
  MeshStore store;
  const auto chain = chain_of_versions(10, 8000);
  const auto& newest = chain.back();
  store.publish(newest);
  const size_t published = store.memory_bytes();
  std::vector<std::shared_ptr<const std::vector<uint8_t>>> made;
  for (size_t b = 0; b <= 8; ++b) made.push_back(newest->delta_from(*chain[b]));
  EXPECT_EQ(newest->delta_from(*chain[1]).get(), made[1].get()) << "base 1 is still cached";
  const auto again = newest->delta_from(*chain[0]);  // base 0 was pushed out by base 8
  EXPECT_NE(again.get(), made[0].get()) << "made again once evicted";
  EXPECT_TRUE(*again == *made[0]) << "the same bytes";
  auto rebuilt = expand(*again, *chain[0]);
  ASSERT_TRUE(rebuilt) << rebuilt.error();
  EXPECT_TRUE(*rebuilt == newest->encoding);
  size_t cached = again->capacity();  // bases 2..8 and 0 now; base 1 went out
  for (size_t b = 2; b <= 8; ++b) cached += made[b]->capacity();
  EXPECT_EQ(store.memory_bytes(), published + cached);
  EXPECT_EQ(newest->delta_from(*chain[2]).get(), made[2].get());
  EXPECT_NE(newest->delta_from(*chain[1]).get(), made[1].get())
      << "base 1 was pushed out by base 0";
}

}  // namespace
}  // namespace vox::pipeline
