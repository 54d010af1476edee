// A level-of-detail mesh made directly from a sampler, as the LOD stage would publish it
// (its encoding): what tests compare the pipeline's meshes with.
#pragma once

#include "proto/mesh_codec.hpp"
#include "server/mesh/lod_block.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/pipeline/lod_mesh_store.hpp"
#include "server/world/point_sampler.hpp"

namespace vox::test {

inline proto::Bytes direct_lod_encoding(const world::PointSampler& sampler,
                                        const pipeline::LodKey& k) {
  mesh::LodBlock block;
  mesh::LodScratch scratch;
  mesh::ChunkMesh mesh;
  proto::CodecScratch codec;
  proto::Bytes out;
  mesh::gather_lod_block(sampler, k.chunk, k.seams, block);
  mesh::mesh_lod_chunk(block, scratch, mesh);
  proto::encode_lod_mesh(mesh, scratch, codec, out);
  return out;
}

}  // namespace vox::test
