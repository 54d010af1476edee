// World benchmarks: terrain generation per chunk kind, and chunk memory.
// Run: build/bin/bench_world (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>

#include "server/world/chunk_map.hpp"
#include "server/world/terrain_generator.hpp"

namespace {

using namespace vox::world;

// Chunks of the 16x8x16 area around the origin, y from -6 to 1: sky, surface and rock.
void BM_GenerateArea(benchmark::State& state) {
  const TerrainGenerator gen(1);
  size_t uniform = 0, chunks = 0;
  for (auto _ : state) {
    for (int z = -8; z < 8; ++z)
      for (int y = -6; y < 2; ++y)
        for (int x = -8; x < 8; ++x) {
          const Chunk c = gen.generate({x, y, z});
          uniform += c.is_uniform();
          ++chunks;
        }
  }
  state.counters["uniform_share"] = static_cast<double>(uniform) / static_cast<double>(chunks);
  state.SetItemsProcessed(static_cast<int64_t>(chunks));
}
BENCHMARK(BM_GenerateArea)->Unit(benchmark::kMillisecond);

void BM_GenerateChunk(benchmark::State& state) {
  const TerrainGenerator gen(1);
  const int y = static_cast<int>(state.range(0));
  int x = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(gen.generate({x++ % 64, y, 3}));
  }
  state.SetItemsProcessed(state.iterations());
}
// y = 4: open sky; -1 and 0: surface; -2: caves; -8: deep rock.
BENCHMARK(BM_GenerateChunk)
    ->Arg(4)
    ->Arg(0)
    ->Arg(-1)
    ->Arg(-2)
    ->Arg(-8)
    ->Unit(benchmark::kMicrosecond);

void BM_ChunkMemory(benchmark::State& state) {
  const TerrainGenerator gen(1);
  ChunkMap map;
  for (auto _ : state) {
    map = ChunkMap();
    for (int z = -8; z < 8; ++z)
      for (int y = -6; y < 2; ++y)
        for (int x = -8; x < 8; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  }
  size_t uniform = 0;
  for (const auto& [c, chunk] : map) uniform += chunk.is_uniform();
  state.counters["chunks"] = static_cast<double>(map.size());
  state.counters["uniform"] = static_cast<double>(uniform);
  state.counters["bytes_uniform_chunk"] = static_cast<double>(Chunk().memory_bytes());
  state.counters["bytes_full_chunk"] = static_cast<double>([] {
    Chunk c;
    c.set(0, 0, 0, {1, 1});
    return c.memory_bytes();
  }());
  state.counters["map_bytes"] = static_cast<double>(map.memory_bytes());
}
BENCHMARK(BM_ChunkMemory)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
