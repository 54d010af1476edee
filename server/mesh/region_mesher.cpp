#include "mesh/region_mesher.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <memory>

#include "mesh/marching_cubes.hpp"
#include "mesh/mesh_welder.hpp"

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
  tbb::enumerable_thread_specific<std::unique_ptr<Worker>> workers([] { return std::make_unique<Worker>(); });
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, meshes.size()), [&](const tbb::blocked_range<size_t>& r) {
      Worker& w = *workers.local();
      for (size_t i = r.begin(); i != r.end(); ++i) {
        gather_padded_block(map, box.at(i), w.block);
        mesh_chunk(w.block, w.scratch, meshes[i]);
      }
    });
  });
  return meshes;
}

ChunkMesh mesh_region(const world::ChunkMap& map, const ChunkBox& box, int threads) {
  const std::vector<ChunkMesh> meshes = mesh_chunks(map, box, threads);
  const float k = static_cast<float>(world::kChunkSize);
  return weld_chunk_grid(meshes, {box.hi.x - box.lo.x + 1, box.hi.y - box.lo.y + 1, box.hi.z - box.lo.z + 1},
                         Vec3f{k * static_cast<float>(box.lo.x), k * static_cast<float>(box.lo.y), k * static_cast<float>(box.lo.z)},
                         threads);
}

}  // namespace vox::mesh
