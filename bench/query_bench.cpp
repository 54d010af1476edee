// Queries about the samples (mesh/surface_query.hpp) on one core: raycasts and ground
// queries through resident terrain (hot) and through terrain generated on demand (cold),
// and a 32^3 sample box. docs/PERFORMANCE.md, "Queries".
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "server/mesh/surface_query.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox {
namespace {

constexpr int kHalf = 4;  // chunks -4..3 on x and z, -2..1 on y

world::ChunkMap area(const world::TerrainGenerator& gen) {
  world::ChunkMap map;
  for (int z = -kHalf; z < kHalf; ++z)
    for (int y = -2; y <= 1; ++y)
      for (int x = -kHalf; x < kHalf; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  return map;
}

// A shot from a player's height at terrain within 100 voxels, or a ground query.
std::vector<mesh::Ray> rays(bool ground, size_t n) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> at(-60, 60), turn(-1, 1);
  std::vector<mesh::Ray> out;
  while (out.size() < n) {
    if (ground) {
      out.push_back({{at(rng), 60, at(rng)}, {0, -1, 0}, 120});
      continue;
    }
    const float d[3] = {turn(rng), -0.4f + 0.3f * turn(rng), turn(rng)};
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    out.push_back(
        {{at(rng) * 0.3f, 30, at(rng) * 0.3f}, {d[0] / len, d[1] / len, d[2] / len}, 100});
  }
  return out;
}

// Generates each chunk the first time a query reads it (a cold world each iteration).
class GeneratingSource final : public mesh::ChunkSource {
 public:
  explicit GeneratingSource(const world::TerrainGenerator& gen) : gen_(gen) {}
  const world::Chunk* chunk(world::ChunkCoord c) override {
    if (const world::Chunk* found = map_.find(c)) return found;
    return &map_.insert(c, gen_.generate(c));
  }
  size_t generated() const { return map_.size(); }

 private:
  const world::TerrainGenerator& gen_;
  world::ChunkMap map_;
};

void BM_QueryHot(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  const world::ChunkMap map = area(gen);
  mesh::ChunkMapSource source(map);
  const std::vector<mesh::Ray> all = rays(state.range(0) == 1, 256);
  size_t i = 0, hits = 0;
  for (auto _ : state) {
    const mesh::RayHit h = mesh::raycast(source, all[i++ % all.size()]);
    hits += h.hit ? 1 : 0;
    benchmark::DoNotOptimize(h);
  }
  state.SetLabel(state.range(0) == 1 ? "ground" : "raycast");
  state.counters["hit_fraction"] = static_cast<double>(hits) / state.iterations();
  state.counters["queries_per_s"] =
      benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_QueryHot)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_QueryCold(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  const std::vector<mesh::Ray> all = rays(state.range(0) == 1, 64);
  size_t i = 0, chunks = 0;
  for (auto _ : state) {
    GeneratingSource source(gen);
    benchmark::DoNotOptimize(mesh::raycast(source, all[i++ % all.size()]));
    chunks += source.generated();
  }
  state.SetLabel(state.range(0) == 1 ? "ground" : "raycast");
  state.counters["chunks_generated"] = static_cast<double>(chunks) / state.iterations();
  state.counters["queries_per_s"] =
      benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_QueryCold)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The worst ray for its length: parallel to a flat surface and just inside the rock, so
// every cell it crosses straddles the surface and none has a triangle it meets; Arg(1)
// runs it along a chunk border, where the samples around each cell lie in two chunks.
void BM_QuerySkimming(benchmark::State& state) {
  world::ChunkMap map;
  world::Chunk flat;
  for (int z = 0; z < world::kChunkSize; ++z)
    for (int x = 0; x < world::kChunkSize; ++x) {
      flat.set(x, 0, z, {16384, world::kStone});
      for (int y = 1; y < world::kChunkSize; ++y) flat.set(x, y, z, {-16384, world::kAir});
    }
  for (int z = -1; z <= 1; ++z)
    for (int x = -1; x <= 17; ++x) {
      map.insert({x, 0, z}, flat);
      map.insert({x, -1, z}, world::Chunk(world::Sample{world::kDensityMax, world::kStone}));
      map.insert({x, 1, z}, world::Chunk());
    }
  mesh::ChunkMapSource source(map);
  const float z = state.range(0) == 1 ? 31.9f : 10.5f;
  const mesh::Ray ray{{0.5f, 0.25f, z}, {1, 0, 0}, 512};
  for (auto _ : state) {
    const mesh::RayHit h = mesh::raycast(source, ray);
    if (h.hit) state.SkipWithError("the skimming ray hit");
    benchmark::DoNotOptimize(h);
  }
  state.SetLabel(state.range(0) == 1 ? "along a chunk border" : "inside chunks");
  state.counters["queries_per_s"] =
      benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_QuerySkimming)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_SampleBox32(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  const world::ChunkMap map = area(gen);
  mesh::ChunkMapSource source(map);
  std::string d, m;
  for (auto _ : state) {
    mesh::read_samples(source, {{-16, -16, -16}, {15, 15, 15}}, d, m);
    benchmark::DoNotOptimize(d.data());
  }
  state.SetItemsProcessed(state.iterations() * 32 * 32 * 32);
}
BENCHMARK(BM_SampleBox32)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace vox

BENCHMARK_MAIN();
