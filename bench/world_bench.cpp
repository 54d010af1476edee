// World benchmarks: terrain generation per chunk kind, chunk memory, and an explosion
// next to protected regions (their cost per edit).
// Run: build/bin/bench_world (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "server/world/chunk_map.hpp"
#include "server/world/collapse.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_undo.hpp"
#include "server/world/region.hpp"
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

// A radius-16 explosion at the surface with `range(0)` protected regions in a grid over
// the 40-voxel cube around it (0: none; 1: one box over an octant; more: smaller boxes
// with gaps). Each iteration finds the edit's protection and applies it to every chunk it
// touches (after the first, the explosion changes nothing, but every sample is visited).
void BM_ExplosionNearRegions(benchmark::State& state) {
  const TerrainGenerator gen(1);
  const int y = static_cast<int>(gen.height_at(16, 16));
  const Edit boom = Explosion{{16, static_cast<float>(y), 16}, 16, 2};
  const std::vector<ChunkCoord> touched = chunks_overlapping(touched_box(boom));
  ChunkMap map;
  for (const ChunkCoord& c : touched) map.insert(c, gen.generate(c));
  const int n = static_cast<int>(state.range(0));
  std::vector<Region> regions;
  const int k = std::max(1, static_cast<int>(std::lround(std::cbrt(n))));
  const int cell = n == 1 ? 20 : 40 / k;
  for (int i = 0; i < n; ++i) {
    Region r;
    r.id = static_cast<uint64_t>(i + 1);
    const int ix = i % k, iy = (i / k) % k, iz = i / (k * k);
    r.box.lo = {-4 + ix * cell, y - 20 + iy * cell, -4 + iz * cell};
    r.box.hi = {r.box.lo[0] + std::max(0, cell - 2), r.box.lo[1] + std::max(0, cell - 2),
                r.box.lo[2] + std::max(0, cell - 2)};
    regions.push_back(r);
  }
  size_t kept = 0;
  for (auto _ : state) {
    const Protection p = protection_for(regions, boom, "mallory");
    kept = p.keep.size();
    for (const ChunkCoord& c : touched)
      benchmark::DoNotOptimize(apply_edit(boom, c, *map.find(c), nullptr, p.keep));
  }
  state.counters["keep_boxes"] = static_cast<double>(kept);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ExplosionNearRegions)
    ->Arg(0)
    ->Arg(1)
    ->Arg(64)
    ->Arg(4096)
    ->Unit(benchmark::kMicrosecond);

// What counting an edit's yield (material_volume.hpp) costs: a radius-8 brush at the
// surface, adding and taking away in turn (every sample in reach changes each time), with
// no tally (0) and with the pipeline's tally per chunk (1).
void BM_BrushYield(benchmark::State& state) {
  const TerrainGenerator gen(1);
  const float y = gen.height_at(16, 16);
  const Edit add = Brush{{16, y, 16}, 8, 1, false, Material{5}};
  const Edit take = Brush{{16, y, 16}, 8, 1, true, Material{0}};
  const std::vector<ChunkCoord> touched = chunks_overlapping(touched_box(add));
  ChunkMap map;
  for (const ChunkCoord& c : touched) map.insert(c, gen.generate(c));
  const bool count = state.range(0) == 1;
  bool adding = true;
  for (auto _ : state) {
    VolumeTally total;
    for (const ChunkCoord& c : touched) {
      VolumeTally part;
      benchmark::DoNotOptimize(
          apply_edit(adding ? add : take, c, *map.find(c), nullptr, {}, count ? &part : nullptr));
      if (count) total.merge(part);
    }
    benchmark::DoNotOptimize(total);
    adding = !adding;
  }
  state.SetLabel(count ? "with the yield" : "without");
  state.counters["chunks"] = static_cast<double>(touched.size());
}
BENCHMARK(BM_BrushYield)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Collapse detection (collapse.hpp) over a 64^3 search box: a radius-10 explosion at the
// surface of generated terrain (caves below), its emptied samples, the pieces it cut loose.
void BM_CollapseSearch64(benchmark::State& state) {
  const TerrainGenerator gen(1);
  const float y = gen.height_at(16, 16);
  const Edit boom = Explosion{{16, y - 4, 16}, 10, 3};
  CollapseLimits limits;
  limits.max_side = 64;
  limits.margin = 32;
  const VoxelBox search = collapse_search_box(touched_box(boom), limits);
  ChunkMap map;
  for (const ChunkCoord& c : chunks_overlapping(
           {{search.lo[0], search.lo[1] - limits.max_fall, search.lo[2]}, search.hi}))
    map.insert(c, gen.generate(c));
  ChunkMap before;
  for (const auto& [c, chunk] : map) before.insert(c, chunk);
  for (const ChunkCoord& c : chunks_overlapping(touched_box(boom)))
    apply_edit(boom, c, *map.find(c), nullptr);
  std::vector<std::array<int32_t, 3>> emptied;
  const VoxelBox t = touched_box(boom);
  for (int z = t.lo[2]; z <= t.hi[2]; ++z)
    for (int yy = t.lo[1]; yy <= t.hi[1]; ++yy)
      for (int x = t.lo[0]; x <= t.hi[0]; ++x)
        if (is_solid(before.sample_at(x, yy, z).density) &&
            !is_solid(map.sample_at(x, yy, z).density))
          emptied.push_back({x, yy, z});
  const SampleAt read = [&](int32_t x, int32_t yy, int32_t z) { return map.sample_at(x, yy, z); };
  size_t pieces = 0;
  for (auto _ : state) pieces = find_detached(read, search, emptied, limits).size();
  state.counters["emptied"] = static_cast<double>(emptied.size());
  state.counters["pieces"] = static_cast<double>(pieces);
}
BENCHMARK(BM_CollapseSearch64)->Unit(benchmark::kMillisecond);

// A rollback's engine (edit_undo.hpp): 20,000 explosions of two players in turn over a
// 1,024 x 1,024 voxel surface (about 1,000 chunks), then one player's 10,000 undone: the
// chunks recomputed from the seed with the other's edits applied again. What an online
// rollback of that size costs in CPU before it is sliced.
void BM_UndoTenThousandEdits(benchmark::State& state) {
  const TerrainGenerator gen(1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> at(0, 1024);
  std::vector<Edit> edits;
  for (int i = 0; i < 20000; ++i) {
    const float x = at(rng), z = at(rng);
    const float y = gen.height_at(static_cast<int32_t>(x), static_cast<int32_t>(z));
    edits.push_back(Explosion{{x, y, z}, 4, 1});
  }
  std::vector<LoggedStep> log;
  for (size_t i = 0; i < edits.size(); ++i)
    log.push_back({i + 1, &edits[i], {}, i % 2 == 1, i % 2 == 1});
  size_t chunks = 0, replayed = 0;
  for (auto _ : state) {
    const UndoResult r = undo_edits(steps_of(log), gen, [](ChunkCoord) { return std::nullopt; });
    chunks = r.chunks.size();
    replayed = r.replayed;
    benchmark::DoNotOptimize(r.chunks.data());
  }
  state.counters["chunks_recomputed"] = static_cast<double>(chunks);
  state.counters["edits_replayed"] = static_cast<double>(replayed);
}
BENCHMARK(BM_UndoTenThousandEdits)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
