#include "server/mesh/region_mesher.hpp"

#include <tbb/enumerable_thread_specific.h>

#include <memory>

#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/mesh_welder.hpp"
#include "server/world/parallel.hpp"

namespace vox::mesh {
namespace {
struct Worker {
  PaddedBlock block;
  MeshScratch scratch;
};
}  // namespace

world::ChunkCoord ChunkBox::at(size_t i) const {
  const auto nx = static_cast<size_t>(hi.x - lo.x + 1), ny = static_cast<size_t>(hi.y - lo.y + 1);
  return {lo.x + static_cast<int32_t>(i % nx), lo.y + static_cast<int32_t>(i / nx % ny),
          lo.z + static_cast<int32_t>(i / nx / ny)};
}

std::vector<ChunkMesh> mesh_chunks(const world::ChunkMap& map, const ChunkBox& box, int threads) {
  std::vector<ChunkMesh> meshes(box.count());
  tbb::enumerable_thread_specific<std::unique_ptr<Worker>> workers(
      [] { return std::make_unique<Worker>(); });
  tbb::task_arena arena(arena_concurrency(threads));
  parallel_for_index(arena, meshes.size(), [&](size_t i) {
    Worker& w = *workers.local();
    gather_padded_block(map, box.at(i), w.block);
    mesh_chunk(w.block, w.scratch, meshes[i]);
  });
  return meshes;
}

ChunkMesh mesh_region(const world::ChunkMap& map, const ChunkBox& box, int threads) {
  const std::vector<ChunkMesh> meshes = mesh_chunks(map, box, threads);
  const float k = static_cast<float>(world::kChunkSize);
  return weld_chunk_grid(
      meshes, {box.hi.x - box.lo.x + 1, box.hi.y - box.lo.y + 1, box.hi.z - box.lo.z + 1},
      Vec3f{k * static_cast<float>(box.lo.x), k * static_cast<float>(box.lo.y),
            k * static_cast<float>(box.lo.z)},
      threads);
}

}  // namespace vox::mesh
