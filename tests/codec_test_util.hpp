// Test helper: a decoded mesh equals the mesher's, up to the encoding's rounding.
#pragma once

#include <gtest/gtest.h>

#include "server/mesh/chunk_mesh.hpp"

namespace vox::test {

// Positions within half a step of 1/1024 (1/2048 for seam vertices, exact), normals within
// 2.6 degrees, materials and indices equal.
inline void expect_same_mesh(const mesh::ChunkMesh& original, const mesh::ChunkMesh& decoded) {
  ASSERT_EQ(decoded.vertex_count(), original.vertex_count());
  ASSERT_EQ(decoded.indices, original.indices);
  constexpr float kTolerance = 0.5f / 1024 + 1e-5f;
  for (size_t v = 0; v < original.vertex_count(); ++v) {
    const auto& a = original.positions[v];
    const auto& b = decoded.positions[v];
    ASSERT_NEAR(a.x, b.x, kTolerance);
    ASSERT_NEAR(a.y, b.y, kTolerance);
    ASSERT_NEAR(a.z, b.z, kTolerance);
    const auto& n = original.normals[v];
    const auto& m = decoded.normals[v];
    ASSERT_GT(n.x * m.x + n.y * m.y + n.z * m.z, 0.999f) << "normal off by more than 2.6 degrees";
    ASSERT_EQ(original.materials[v], decoded.materials[v]);
  }
}

}  // namespace vox::test
