// The world pipeline's re-mesh pass: dirty chunks meshed in parallel, the meshes that
// changed encoded and published as new versions. Pipeline thread (see world_pipeline.hpp).
#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

bool same_mesh(const mesh::ChunkMesh& a, const mesh::ChunkMesh& b) {
  return a.indices == b.indices && a.positions == b.positions && a.normals == b.normals &&
         a.materials == b.materials;
}

}  // namespace

std::shared_ptr<MeshVersion> remesh_chunk(MeshWorker& w, const world::ChunkMap& chunks,
                                          ChunkCoord c, const MeshVersion* previous) {
  mesh::gather_padded_block(chunks, c, w.block);
  mesh::mesh_chunk(w.block, w.scratch, w.mesh);
  if (previous && same_mesh(previous->mesh, w.mesh)) return nullptr;
  // A new version: the only allocations, each of its final size (the worker's warm
  // buffers took the mesher's writes).
  auto version = std::make_shared<MeshVersion>();
  version->coord = c;
  version->mesh.positions.assign(w.mesh.positions.begin(), w.mesh.positions.end());
  version->mesh.normals.assign(w.mesh.normals.begin(), w.mesh.normals.end());
  version->mesh.materials.assign(w.mesh.materials.begin(), w.mesh.materials.end());
  version->mesh.indices.assign(w.mesh.indices.begin(), w.mesh.indices.end());
  version->triangles = static_cast<uint32_t>(w.mesh.triangle_count());
  // Encoded once here, while the mesher's topology is at hand; every client shares it.
  proto::encode_mesh(version->mesh, w.scratch, w.block.cells, w.codec, version->encoding);
  // A re-mesh's clients take deltas: its full frame is made when someone asks for it.
  if (!previous) w.zstd.compress(version->encoding, {}, version->full_frame);
  return version;
}

// Re-meshes every dirty chunk once, in parallel, encodes the meshes that changed and
// publishes them as new versions. Returns the chunks given a new version.
std::vector<ChunkCoord> WorldPipeline::remesh_and_publish(std::vector<ChunkCoord>& dirty,
                                                          const EditTimes* edited_at) {
  FreshMeshes fresh = remesh(dirty);
  return publish(dirty, fresh, edited_at);
}

FreshMeshes WorldPipeline::remesh(std::vector<ChunkCoord>& dirty) {
  WorldState& st = *state_;
  const Clock::time_point start = Clock::now();
  std::sort(dirty.begin(), dirty.end());
  dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
  FreshMeshes fresh(dirty.size());
  std::vector<MeshVersionPtr> previous(dirty.size());
  for (size_t i = 0; i < dirty.size(); ++i) previous[i] = newest_mesh(dirty[i]);
  parallel_for_index(st.arena, dirty.size(), [&](size_t i) {
    fresh[i] = remesh_chunk(*st.workers.local(), st.chunks, dirty[i], previous[i].get());
  });
  if (observer_.remesh && !dirty.empty()) observer_.remesh(seconds_since(start), dirty.size());
  return fresh;
}

std::vector<ChunkCoord> WorldPipeline::publish(const std::vector<ChunkCoord>& dirty,
                                               FreshMeshes& fresh, const EditTimes* edited_at) {
  WorldState& st = *state_;
  // An edit batch re-meshed only meshed chunks: one not resident now, or not meshed, was
  // evicted (and maybe loaded again) while the batch waited for the store, and its mesh
  // is made again when it is next viewed.
  std::vector<char> current(dirty.size());
  for (size_t i = 0; i < dirty.size(); ++i) {
    auto it = st.info.find(dirty[i]);
    current[i] = it != st.info.end() && (!edited_at || it->second.meshed);
    if (current[i]) it->second.meshed = true;
  }
  std::vector<ChunkCoord> published;
  for (size_t i = 0; i < dirty.size(); ++i) {
    if (!fresh[i] || !current[i]) continue;
    fresh[i]->version = st.next_version++;
    if (edited_at) {
      if (auto it = edited_at->find(dirty[i]); it != edited_at->end())
        fresh[i]->edited_at = it->second;
    }
    meshes_.publish(std::move(fresh[i]));
    published.push_back(dirty[i]);
  }
  return published;
}

}  // namespace vox::pipeline
