// World pipeline benchmarks: edit latency (submit -> every new mesh published), sustained
// edit throughput, and cold start of a view. Run: build/bin/bench_pipeline.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include "server/pipeline/world_pipeline.hpp"

namespace {

using namespace vox;
using Clock = std::chrono::steady_clock;

constexpr uint64_t kSeed = 1;
// The loaded 8x4x8-chunk area around the origin, y layers around the surface.
const mesh::ChunkBox kArea{{-4, -2, -4}, {3, 1, 3}};

// A random point on the terrain surface inside the area.
world::Vec3 surface_point(const world::TerrainGenerator& gen, std::mt19937& rng) {
  std::uniform_real_distribution<float> xz(-4 * 32.0f + 8, 4 * 32.0f - 8);
  const float x = xz(rng), z = xz(rng);
  return {x, gen.height_at(static_cast<int>(x), static_cast<int>(z)), z};
}

void report_percentiles(benchmark::State& state, std::vector<double>& us) {
  std::sort(us.begin(), us.end());
  state.counters["p50_us"] = us[us.size() / 2];
  state.counters["p90_us"] = us[us.size() * 9 / 10];
  state.counters["p99_us"] = us[us.size() * 99 / 100];
  state.counters["max_us"] = us.back();
}

template <class MakeEdit>
void edit_latency(benchmark::State& state, MakeEdit make_edit) {
  pipeline::WorldPipeline p(pipeline::PipelineConfig{.seed = kSeed, .threads = 2});
  p.load(kArea).get();
  const world::TerrainGenerator gen(kSeed);
  std::mt19937 rng(42);
  std::vector<double> us;
  size_t chunks = 0;
  for (auto _ : state) {
    const world::Edit edit = make_edit(surface_point(gen, rng));
    const auto t0 = Clock::now();
    const pipeline::EditResult r = p.submit(edit).get();
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    chunks += r.changed_chunks.size();
  }
  report_percentiles(state, us);
  state.counters["chunks_per_edit"] = static_cast<double>(chunks) / static_cast<double>(us.size());
}

void BM_BrushRadius4Latency(benchmark::State& state) {
  edit_latency(state, [](world::Vec3 at) { return world::Brush{at, 4, 0.8f}; });
}
BENCHMARK(BM_BrushRadius4Latency)->Iterations(2000)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_ExplosionRadius16Latency(benchmark::State& state) {
  edit_latency(state, [](world::Vec3 at) { return world::Explosion{at, 16, 2}; });
}
BENCHMARK(BM_ExplosionRadius16Latency)
    ->Iterations(300)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// Open loop: brushes of radius 3 at random positions submitted at a fixed rate for 3 s;
// reports the rate achieved with every mesh published, and the largest queue seen.
void BM_SustainedBrushes(benchmark::State& state) {
  const double rate = static_cast<double>(state.range(0));
  for (auto _ : state) {
    pipeline::WorldPipeline p(pipeline::PipelineConfig{.seed = kSeed, .threads = 2});
    p.load(kArea).get();
    const world::TerrainGenerator gen(kSeed);
    std::mt19937 rng(7);
    std::atomic<size_t> done{0};
    size_t max_queue = 0, sent = 0;
    const auto t0 = Clock::now();
    const auto duration = std::chrono::seconds(3);
    while (Clock::now() - t0 < duration) {
      const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
      while (static_cast<double>(sent) < elapsed * rate) {
        p.submit(
            world::Brush{surface_point(gen, rng), 3, 0.6f, (sent % 2) == 1, std::nullopt},
            [&done](const pipeline::EditResult&) { done.fetch_add(1, std::memory_order_relaxed); });
        ++sent;
      }
      max_queue = std::max(max_queue, p.stats().queued_edits);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    const size_t done_in_time = done.load();
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    while (done.load() < sent) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    const double drain_ms =
        std::chrono::duration<double, std::milli>(Clock::now() - t0).count() - seconds * 1000;
    const auto stats = p.stats();
    state.counters["completed_per_s"] = static_cast<double>(done_in_time) / seconds;
    state.counters["max_queue"] = static_cast<double>(max_queue);
    state.counters["drain_ms"] = drain_ms;
    state.counters["batches"] = static_cast<double>(stats.batches);
    state.counters["meshes_published"] = static_cast<double>(stats.meshes_published);
  }
}
BENCHMARK(BM_SustainedBrushes)
    ->Arg(5000)
    ->Arg(10000)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Closed loop: 30,000 brushes submitted at once; edits per second until all published.
void BM_BrushThroughput(benchmark::State& state) {
  for (auto _ : state) {
    pipeline::WorldPipeline p(pipeline::PipelineConfig{.seed = kSeed, .threads = 2});
    p.load(kArea).get();
    const world::TerrainGenerator gen(kSeed);
    std::mt19937 rng(9);
    std::vector<world::Edit> edits;
    for (int i = 0; i < 30000; ++i)
      edits.push_back(world::Brush{surface_point(gen, rng), 3, 0.6f, (i % 2) == 1, std::nullopt});
    std::atomic<size_t> done{0};
    const auto t0 = Clock::now();
    for (auto& e : edits)
      p.submit(std::move(e), [&done](const pipeline::EditResult&) { done.fetch_add(1); });
    while (done.load() < 30000) std::this_thread::sleep_for(std::chrono::microseconds(100));
    state.counters["edits_per_s"] =
        30000 / std::chrono::duration<double>(Clock::now() - t0).count();
  }
}
BENCHMARK(BM_BrushThroughput)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// A fresh pipeline loads the 17x17x17 chunks within radius 8 of a surface chunk:
// generation and meshing of everything, on both cores.
void BM_ColdStartViewRadius8(benchmark::State& state) {
  const world::TerrainGenerator gen(kSeed);
  const int cy = world::floor_div(static_cast<int>(std::floor(gen.height_at(16, 16))), 32);
  for (auto _ : state) {
    pipeline::WorldPipeline p(pipeline::PipelineConfig{.seed = kSeed, .threads = 2});
    const auto t0 = Clock::now();
    p.load({{-8, cy - 8, -8}, {8, cy + 8, 8}}).get();
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    const auto s = p.stats();
    state.counters["chunks_generated"] = static_cast<double>(s.chunks_generated);
    state.counters["meshes"] = static_cast<double>(s.mesh_count);
    state.counters["chunk_MB"] = static_cast<double>(s.chunk_bytes) / 1e6;
    state.counters["mesh_MB"] = static_cast<double>(s.mesh_bytes) / 1e6;
  }
}
BENCHMARK(BM_ColdStartViewRadius8)->Iterations(5)->Unit(benchmark::kMillisecond)->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
