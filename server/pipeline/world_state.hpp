// The pipeline thread's world: the chunk map, per-chunk residency (modified, meshed, last
// used), the mesh workers, generation of missing chunks and eviction. Pipeline thread only;
// nothing here is synchronised.
#pragma once

#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/padded_block.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/pipeline/view_index.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

struct MeshWorker {
  mesh::PaddedBlock block;
  mesh::MeshScratch scratch;
  mesh::ChunkMesh mesh;   // meshed and encoded into first: a mesh that did not change
  proto::Bytes encoding;  // allocates nothing
  proto::CodecScratch codec;
  proto::ZstdCodec zstd;
};

struct WorldState {
  explicit WorldState(int threads);

  struct ChunkInfo {
    bool modified = false;  // differs from the generated terrain
    // Changed since the last checkpoint; or being written by one. Either keeps it resident
    // (the store does not have it yet); a modified chunk without them may be evicted.
    bool unsaved = false, checkpointing = false;
    bool meshed = false;  // its mesh is in the store (so its neighbours were loaded)
    Clock::time_point last_used;
  };
  world::ChunkMap chunks;
  std::unordered_map<world::ChunkCoord, ChunkInfo, world::ChunkCoordHash> info;
  tbb::task_arena arena;
  tbb::enumerable_thread_specific<std::unique_ptr<MeshWorker>> workers{
      [] { return std::make_unique<MeshWorker>(); }};
  uint64_t next_version = 1;
  size_t modified_count = 0;  // resident chunks with info.modified
  // Chunks the store has a checkpoint of (resident or not): loaded from it, never
  // generated. `read_stored` reads one (throws store::StoreError).
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> stored;
  std::function<world::Chunk(world::ChunkCoord)> read_stored;
  // Surface heights of the columns generated during one load pass.
  std::map<std::pair<int32_t, int32_t>, std::shared_ptr<const world::ColumnHeights>> column_heights;
  // A cluster node's: whether saved modified chunk c may be evicted now (only while its
  // zone is held and caught up: docs/CLUSTER.md, "Evicting a zone's chunks"); asked just
  // before c goes. Null: every saved chunk may.
  std::function<bool(world::ChunkCoord)> may_evict_modified;
  ViewIndex views;  // every session's current view: chunks in one are never evicted
  // Chunks a waiting mesh needs (the 3x3x3 around it), with how many need each: never
  // evicted, or a mesh waiting for its last neighbour could lose the others meanwhile.
  std::unordered_map<world::ChunkCoord, uint32_t, world::ChunkCoordHash> pins;
  void pin_neighbourhood(world::ChunkCoord c);
  void unpin_neighbourhood(world::ChunkCoord c);

  // Loads a missing stored chunk from the store (modified, saved). Throws StoreError.
  void load_stored(world::ChunkCoord c, Clock::time_point now);
  // Generates every chunk of `coords` that is missing, in parallel over columns so each
  // column's surface heights are computed once (stored ones are read from the store: may
  // throw StoreError); marks present ones used. Returns the number generated.
  size_t ensure_loaded(const std::vector<world::ChunkCoord>& coords,
                       const world::TerrainGenerator& gen, Clock::time_point now);

  // Drops saved chunks (unmodified, or modified and checkpointed; and their meshes) that are in no
  // view and whose mesh no one but the store holds, least recently used first: every one unused for
  // `idle`, then more until the chunks and meshes take at most `target_bytes`. A chunk used within
  // `min_age` always stays. Returns the number dropped.
  // Looks at most `max_scan` chunks, continuing where the last call stopped (a pass under
  // memory pressure must not stall a batch on a scan of the whole world).
  size_t evict(MeshStore& meshes, Clock::time_point now, std::chrono::milliseconds idle,
               std::chrono::milliseconds min_age, size_t target_bytes, size_t max_scan = SIZE_MAX);

 private:
  size_t evict_cursor_ = 0;  // the bucket of `info` the next limited scan starts at
};

}  // namespace vox::pipeline
