// Meshes shared by the mesh decoder fuzzer and its seed corpus generator: a ball in a
// small block, meshed and encoded as the server does. The fuzzer's delta base is
// sphere_encoding(kBaseRadius, kBaseMaterial), so the seed deltas apply to it.
#pragma once

#include <cmath>
#include <memory>

#include "proto/mesh_codec.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/padded_block.hpp"
#include "server/world/point_sampler.hpp"
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

// A level-1 chunk (format 2) with a ball across its -x face and -y/-x edge, seams on both:
// the fuzzer's structured mutations start from it.
inline proto::Bytes lod_sphere_encoding() {
  struct Ball : world::PointSampler {
    void sample_grid(const std::array<int32_t, 3>& o, int32_t step, const std::array<int, 3>& n,
                     world::Sample* out) const override {
      for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
          for (int i = 0; i < n[0]; ++i, ++out) {
            const float x = static_cast<float>(o[0] + step * i) - 1.3f,
                        y = static_cast<float>(o[1] + step * j) - 2.6f,
                        z = static_cast<float>(o[2] + step * k) - 30.2f;
            const float d = 9.5f - std::sqrt(x * x + y * y + z * z);
            out->density = world::quantize_density(d / 8);
            out->material = d > 0 ? 5 : world::kAir;
          }
    }
  };
  auto block = std::make_unique<mesh::LodBlock>();
  auto lod = std::make_unique<mesh::LodScratch>();
  auto scratch = std::make_unique<proto::CodecScratch>();
  mesh::gather_lod_block(Ball{}, {1, {0, 0, 0}}, {world::kMinusX, 1u << world::lod_edge(2, 0, 0)},
                         *block);
  mesh::ChunkMesh mesh;
  mesh::mesh_lod_chunk(*block, *lod, mesh);
  proto::Bytes out;
  proto::encode_lod_mesh(mesh, *lod, *scratch, out);
  return out;
}

}  // namespace vox::fuzz
