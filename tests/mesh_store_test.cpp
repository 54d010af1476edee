#include "server/pipeline/mesh_store.hpp"

#include <gtest/gtest.h>

#include <vector>

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

}  // namespace
}  // namespace vox::pipeline
