// Re-meshing and publication, as functions of what they read and write: dirty chunks
// meshed in parallel on the world state's mesh workers (each against the newest mesh a
// pending batch or the store holds, so an unchanged mesh allocates nothing), then the
// changed meshes given their version numbers and published as immutable versions.
// Pipeline thread only, but remesh_chunk (any one thread per worker).
#pragma once

#include <memory>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/world/chunk_map.hpp"

namespace vox::pipeline {

struct WorldState;
struct MeshWorker;
class DurableCommit;

// Meshes and encodes chunk c into the worker's buffers; when the encoding differs from
// `previous`'s (or there is none), a new version of it (coordinate, triangle count,
// encoding, zstd frame; version number and edit time not set). Null when it did not
// change: then, once the worker's buffers are warm, nothing is allocated. Any one thread
// per worker.
std::shared_ptr<MeshVersion> remesh_chunk(MeshWorker& w, const world::ChunkMap& chunks,
                                          world::ChunkCoord c, const MeshVersion* previous);

// Sorts and deduplicates `dirty`, then meshes each chunk of it once, in parallel; a chunk
// whose mesh did not change against the newest version (a pending batch's in `pending`,
// else the published one) gets null.
FreshMeshes remesh(WorldState& state, std::vector<world::ChunkCoord>& dirty,
                   const MeshStore& published, const DurableCommit* pending);

// Gives the changed meshes of `dirty` their versions and publishes them; returns their
// chunks. `edited_at`: an edit batch's (its meshes carry their oldest edit's time; a chunk
// not meshed any more was evicted while the batch waited for the store and is skipped);
// null for a load's meshes.
std::vector<world::ChunkCoord> publish(WorldState& state, MeshStore& meshes,
                                       const std::vector<world::ChunkCoord>& dirty,
                                       FreshMeshes& fresh, const EditTimes* edited_at);

}  // namespace vox::pipeline
