// How a LOD pass shares its chunks between re-meshes and missing meshes
// (server/pipeline/lod_pass_quota.hpp).
#include "server/pipeline/lod_pass_quota.hpp"

#include <gtest/gtest.h>

namespace vox::pipeline {
namespace {

TEST(LodPassQuota, ReMeshesAndMissingMeshesShareAPassWhenBothWait) {
  EXPECT_EQ(lod_remesh_quota(2, 0, false), 2u);
  EXPECT_EQ(lod_remesh_quota(2, 0, true), 1u);
  EXPECT_EQ(lod_missing_quota(2, 1, true), 1u);
  EXPECT_EQ(lod_remesh_quota(8, 0, true), 4u);
  EXPECT_EQ(lod_missing_quota(8, 4, true), 4u);
  EXPECT_EQ(lod_missing_quota(8, 1, true), 7u) << "fewer re-meshes due: more missing ones";
  EXPECT_EQ(lod_missing_quota(8, 1, false), 0u);
}

// The bug (found in review): with more chunks put off by the store than a pass holds,
// max_chunks - chunks wrapped around and one pass took every missing mesh of every owner,
// stalling the pipeline thread.
TEST(LodPassQuota, ABacklogTheStorePutOffNeitherWrapsNorStopsMissingMeshes) {
  EXPECT_EQ(lod_remesh_quota(2, 3, true), 0u);
  EXPECT_EQ(lod_remesh_quota(2, 3, false), 0u);
  EXPECT_EQ(lod_missing_quota(2, 3, true), 1u) << "one missing mesh still gets through";
  EXPECT_EQ(lod_missing_quota(2, 1000, true), 1u);
}

// With edits at 0.5 a second per player, 200 players' first views waited 8 to 14 s: each
// pass took one re-mesh (a chunk's every seams variant, 5 to 10 meshes) beside one
// missing mesh. While a first view waits, re-meshes take one pass in kFirstViewRemeshTurn.
TEST(LodPassQuota, WhileAFirstViewWaitsReMeshesTakeOnePassInEight) {
  int turns = 0;
  for (uint64_t pass = 1; pass <= 64; ++pass) turns += lod_remesh_turn(true, pass) ? 1 : 0;
  EXPECT_EQ(turns, 64 / static_cast<int>(kFirstViewRemeshTurn));
  for (uint64_t pass = 1; pass <= 64; ++pass)
    EXPECT_TRUE(lod_remesh_turn(false, pass)) << "no first view waits: every pass";
}

}  // namespace
}  // namespace vox::pipeline
