#include "server/pipeline/remesh.hpp"

#include <algorithm>

#include "server/pipeline/durable_commit.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

std::shared_ptr<MeshVersion> remesh_chunk(MeshWorker& w, const world::ChunkMap& chunks,
                                          ChunkCoord c, const MeshVersion* previous) {
  mesh::gather_padded_block(chunks, c, w.block);
  mesh::mesh_chunk(w.block, w.scratch, w.mesh);
  // Encoded once here, while the mesher's topology is at hand; every client shares it. Two
  // meshes with one encoding look the same to every client: no new version.
  proto::encode_mesh(w.mesh, w.scratch, w.block.cells, w.codec, w.encoding);
  if (previous && std::equal(previous->encoding.begin(), previous->encoding.end(),
                             w.encoding.begin(), w.encoding.end()))
    return nullptr;
  // A new version: the only allocations, each of its final size.
  auto version = std::make_shared<MeshVersion>();
  version->coord = c;
  version->triangles = static_cast<uint32_t>(w.mesh.triangle_count());
  version->encoding.assign(w.encoding.begin(), w.encoding.end());
  // Its clients take deltas, most from the version before (made here, in parallel, not
  // by the network thread for the first of them); a chunk that had none goes in full.
  if (!previous) {
    w.zstd.compress(version->encoding, {}, version->full_frame);
  } else if (previous->version != 0) {  // 0: a batch still waiting for its append
    version->premake_delta(*previous, w.zstd);
  }
  return version;
}

FreshMeshes remesh(WorldState& st, std::vector<ChunkCoord>& dirty, const MeshStore& published,
                   const DurableCommit* pending) {
  std::sort(dirty.begin(), dirty.end());
  dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
  FreshMeshes fresh(dirty.size());
  std::vector<MeshVersionPtr> previous(dirty.size());
  for (size_t i = 0; i < dirty.size(); ++i) {
    if (pending) previous[i] = pending->newest_mesh(dirty[i]);
    if (!previous[i]) previous[i] = published.get(dirty[i]);
  }
  parallel_for_index(st.arena, dirty.size(), [&](size_t i) {
    fresh[i] = remesh_chunk(*st.workers.local(), st.chunks, dirty[i], previous[i].get());
  });
  return fresh;
}

std::vector<ChunkCoord> publish(WorldState& st, MeshStore& meshes,
                                const std::vector<ChunkCoord>& dirty, FreshMeshes& fresh,
                                const EditTimes* edited_at) {
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
    meshes.publish(std::move(fresh[i]));
    published.push_back(dirty[i]);
  }
  return published;
}

}  // namespace vox::pipeline
