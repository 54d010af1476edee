// Mesher benchmarks: one terrain chunk, the 257x129x257 volume on 1 and 2 threads, and a
// dense worst case. Run: build/bin/bench_mesher (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/volume_mesher.hpp"
#include "server/world/gradient_noise.hpp"
#include "server/world/terrain_generator.hpp"

namespace {

using namespace vox;

// Padded blocks of every chunk the surface crosses in a 16x4x16-chunk terrain area.
struct TerrainBlocks {
  std::vector<std::unique_ptr<mesh::PaddedBlock>> blocks;
  TerrainBlocks() {
    const world::TerrainGenerator gen(1);
    world::ChunkMap map;
    for (int z = -9; z <= 8; ++z)
      for (int y = -4; y <= 2; ++y)
        for (int x = -9; x <= 8; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
    mesh::MeshScratch scratch;
    mesh::ChunkMesh m;
    for (int z = -8; z < 8; ++z)
      for (int y = -3; y < 2; ++y)
        for (int x = -8; x < 8; ++x) {
          auto block = std::make_unique<mesh::PaddedBlock>();
          mesh::gather_padded_block(map, {x, y, z}, *block);
          mesh::mesh_chunk(*block, scratch, m);
          if (!m.empty()) blocks.push_back(std::move(block));
        }
  }
};
const TerrainBlocks& terrain_blocks() {
  static const TerrainBlocks blocks;
  return blocks;
}

void BM_MeshTerrainChunk(benchmark::State& state) {
  const auto& blocks = terrain_blocks().blocks;
  mesh::MeshScratch scratch;
  mesh::ChunkMesh m;
  size_t i = 0, triangles = 0, chunks = 0;
  for (auto _ : state) {
    mesh::mesh_chunk(*blocks[i], scratch, m);
    triangles += m.triangle_count();
    ++chunks;
    i = (i + 1) % blocks.size();
    benchmark::DoNotOptimize(m.indices.data());
  }
  // Median over the chunks of each chunk's best of 5 runs.
  std::vector<double> per_chunk;
  for (const auto& block : blocks) {
    double best = 1e9;
    for (int r = 0; r < 5; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      mesh::mesh_chunk(*block, scratch, m);
      best = std::min(
          best,
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    }
    per_chunk.push_back(best);
  }
  std::sort(per_chunk.begin(), per_chunk.end());
  state.counters["median_us"] = per_chunk[per_chunk.size() / 2];
  state.counters["p90_us"] = per_chunk[per_chunk.size() * 9 / 10];
  state.counters["chunks_in_set"] = static_cast<double>(blocks.size());
  state.counters["tris_per_chunk"] = static_cast<double>(triangles) / static_cast<double>(chunks);
  state.SetItemsProcessed(static_cast<int64_t>(chunks) * 32 * 32 * 32);
}
BENCHMARK(BM_MeshTerrainChunk)->Unit(benchmark::kMicrosecond);

void BM_GatherPaddedBlock(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  world::ChunkMap map;
  for (int z = -1; z <= 1; ++z)
    for (int y = -1; y <= 1; ++y)
      for (int x = -1; x <= 1; ++x) map.insert({x, y, z}, gen.generate({x, y - 1, z}));
  mesh::PaddedBlock block;
  for (auto _ : state) {
    mesh::gather_padded_block(map, {0, 0, 0}, block);
    benchmark::DoNotOptimize(block.density.get());
  }
}
BENCHMARK(BM_GatherPaddedBlock)->Unit(benchmark::kMicrosecond);

// The terrain of seed 1 sampled on a 257x129x257 grid (y from -64), quantised once.
const mesh::QuantizedVolume& terrain_volume() {
  static const mesh::QuantizedVolume volume = [] {
    const world::TerrainGenerator gen(1);
    mesh::QuantizedVolume v;
    v.dims = {257, 129, 257};
    v.density.resize(static_cast<size_t>(257) * 129 * 257);
    for (int z = 0; z < 257; ++z)
      for (int y = 0; y < 129; ++y)
        for (int x = 0; x < 257; ++x)
          v.density[x + 257 * (y + 129 * static_cast<size_t>(z))] =
              gen.sample_at(x - 128, y - 64, z - 128).density;
    return v;
  }();
  return volume;
}

void BM_MeshVolume257x129x257(benchmark::State& state) {
  const auto& volume = terrain_volume();
  size_t triangles = 0;
  for (auto _ : state) {
    const mesh::ChunkMesh m = mesh::mesh_volume(volume, static_cast<int>(state.range(0)));
    triangles = m.triangle_count();
  }
  state.counters["triangles"] = static_cast<double>(triangles);
  state.SetItemsProcessed(state.iterations() * 256 * 128 * 256);  // cells
}
BENCHMARK(BM_MeshVolume257x129x257)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The voxel-cli mesh path: the same terrain as floats, quantised while each chunk's block
// is gathered (no int16 copy of the volume), meshed and welded.
void BM_MeshFloatVolume257x129x257(benchmark::State& state) {
  const auto& volume = terrain_volume();
  std::vector<float> values(volume.density.size());
  for (size_t i = 0; i < values.size(); ++i)
    values[i] = world::dequantize_density(volume.density[i]);
  const mesh::VolumeMeshOptions options{
      .iso = 0.0f, .invert = false, .threads = static_cast<int>(state.range(0))};
  size_t triangles = 0;
  for (auto _ : state) {
    const mesh::ChunkMesh m = mesh::mesh_float_volume({volume.dims, values, {}}, options);
    triangles = m.triangle_count();
  }
  state.counters["triangles"] = static_cast<double>(triangles);
  state.SetItemsProcessed(state.iterations() * 256 * 128 * 256);  // cells
}
BENCHMARK(BM_MeshFloatVolume257x129x257)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_QuantizeVolume257x129x257(benchmark::State& state) {
  mesh::Volume v;
  v.dims = {257, 129, 257};
  v.values.resize(static_cast<size_t>(257) * 129 * 257);
  for (size_t i = 0; i < v.values.size(); ++i)
    v.values[i] = std::sin(static_cast<float>(i) * 0.001f);
  for (auto _ : state) benchmark::DoNotOptimize(mesh::quantize_volume(v, {}).density.data());
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(v.values.size()));
}
BENCHMARK(BM_QuantizeVolume257x129x257)->Unit(benchmark::kMillisecond);

// Worst case: noise at about two samples per period, so nearly every cell is cut.
void BM_MeshDenseWorstCase(benchmark::State& state) {
  const world::GradientNoise noise(3);
  mesh::PaddedBlock block;
  for (int z = -1; z <= 33; ++z)
    for (int y = -1; y <= 33; ++y)
      for (int x = -1; x <= 33; ++x)
        block.density[mesh::PaddedBlock::index(x, y, z)] = world::quantize_density(
            noise.noise3(x * 0.93f + 0.31f, y * 0.87f + 0.17f, z * 0.91f + 0.53f));
  mesh::MeshScratch scratch;
  mesh::ChunkMesh m;
  for (auto _ : state) {
    mesh::mesh_chunk(block, scratch, m);
    benchmark::DoNotOptimize(m.indices.data());
  }
  state.counters["triangles"] = static_cast<double>(m.triangle_count());
  state.SetItemsProcessed(state.iterations() * 32 * 32 * 32);
}
BENCHMARK(BM_MeshDenseWorstCase)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
