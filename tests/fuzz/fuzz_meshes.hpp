// Meshes shared by the mesh decoder fuzzer and its seed corpus generator: a ball in a
// small block, meshed and encoded as the server does. The fuzzer's delta base is
// sphere_encoding(kBaseRadius, kBaseMaterial), so the seed deltas apply to it.
#pragma once

#include <cmath>
#include <memory>

#include "proto/mesh_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/padded_block.hpp"
#include "server/world/sample.hpp"

namespace vox::fuzz {

inline constexpr int kSphereCells = 10;  // a small block: small seeds, fast executions
inline constexpr float kBaseRadius = 3.7f;
inline constexpr world::Material kBaseMaterial = 3;

inline proto::Bytes sphere_encoding(float radius, world::Material material) {
  mesh::PaddedBlock block;
  block.cells = {kSphereCells, kSphereCells, kSphereCells};
  const float c = kSphereCells / 2.0f - 0.3f;
  for (int z = -1; z <= world::kChunkSize + 1; ++z)
    for (int y = -1; y <= world::kChunkSize + 1; ++y)
      for (int x = -1; x <= world::kChunkSize + 1; ++x) {
        const float d =
            radius - std::sqrt((x - c) * (x - c) + (y - c) * (y - c) + (z - c) * (z - c));
        const int i = mesh::PaddedBlock::index(x, y, z);
        block.density[i] = world::quantize_density(d / 4);
        block.material[i] = d > 0 ? material : world::kAir;
      }
  auto topology = std::make_unique<mesh::MeshScratch>();
  auto scratch = std::make_unique<proto::CodecScratch>();
  mesh::ChunkMesh mesh;
  mesh::mesh_chunk(block, *topology, mesh);
  proto::Bytes out;
  proto::encode_mesh(mesh, *topology, block.cells, *scratch, out);
  return out;
}

}  // namespace vox::fuzz
