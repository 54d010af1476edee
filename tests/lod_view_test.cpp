// One client's level-of-detail view (server/world/lod_view.hpp): what is sent and unloaded
// as the eye moves.
#include "server/world/lod_view.hpp"

#include <gtest/gtest.h>

#include <random>

namespace vox::world {
namespace {

const LodSettings kSettings{
    .levels = 5, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0};

LodSeamsMap layout_with_seams(const LodLayout& layout) {
  LodSeamsMap out;
  for (const LodChunk& c : layout.chunks()) out.emplace(c, layout.seams(c));
  return out;
}

TEST(LodView, TheFirstViewSendsEveryChunkNearestFirstThenFinerFirst) {
  LodView view(kSettings);
  const std::array<double, 3> eye{100.5, 20.5, -300.25};
  const LodViewChange change = view.update(eye);
  EXPECT_TRUE(change.unload.empty());
  EXPECT_EQ(change.send.size(), view.layout().chunks().size());
  for (size_t i = 1; i < change.send.size(); ++i) {
    const double a = distance_to(change.send[i - 1].first, eye),
                 b = distance_to(change.send[i].first, eye);
    ASSERT_LE(a, b);
    if (a == b) {
      ASSERT_LE(change.send[i - 1].first.level, change.send[i].first.level);
    }
  }
  EXPECT_EQ(view.held(), layout_with_seams(view.layout()));
}

TEST(LodView, MovingSendsOnlyNewChunksAndChangedSeamsAndUnloadsWhatLeft) {
  LodView view(kSettings);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> step(-90.0, 90.0);
  std::array<double, 3> eye{10.5, 0.5, 10.5};
  LodSeamsMap client;  // what the client holds, from the changes alone
  size_t resent_for_seams = 0;
  for (int move = 0; move < 30; ++move) {
    const LodViewChange change = view.update(eye);
    for (const LodChunk& c : change.unload) ASSERT_EQ(client.erase(c), 1u) << "unloads held";
    for (const auto& [c, seams] : change.send) {
      const auto it = client.find(c);
      if (it != client.end()) {
        ASSERT_NE(it->second, seams) << "resent only for other seams";
        ++resent_for_seams;
      }
      client[c] = seams;
    }
    ASSERT_EQ(client, layout_with_seams(view.layout()));
    for (int a = 0; a < 3; ++a) eye[a] += step(rng) * (a == 1 ? 0.2 : 1.0);
  }
  EXPECT_GT(resent_for_seams, 0u);
}

TEST(LodView, MovingBackAndForthAcrossABoundaryReloadsNothing) {
  LodView view(kSettings);
  std::array<double, 3> eye{5.5, 5.5, 5.5};
  view.update(eye);
  double x = eye[0];
  for (int i = 0; i < 3000 && view.update({x, eye[1], eye[2]}).empty(); ++i) x += 1.0;
  for (int i = 0; i < 20; ++i) {
    EXPECT_TRUE(view.update({x - 1.0, eye[1], eye[2]}).empty()) << i;
    EXPECT_TRUE(view.update({x, eye[1], eye[2]}).empty()) << i;
  }
}

}  // namespace
}  // namespace vox::world
