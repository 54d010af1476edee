// voxeld over loopback: edit -> every changed chunk's delta received and decoded, and a
// fresh client's radius-8 view. Starts a real voxeld (like the integration tests).
// Run: build/bin/bench_server (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "client/voxel_client.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/server_process.hpp"

namespace {

using namespace vox;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

void drain(client::Client& c, std::chrono::milliseconds quiet, Clock::time_point* last = nullptr,
           size_t* meshes = nullptr, size_t* bytes = nullptr) {
  while (auto m = c.receive(quiet)) {
    if (m->has_chunk_mesh()) {
      if (c.apply(m->chunk_mesh())) std::abort();
      if (meshes) ++*meshes;
      if (bytes) *bytes += m->chunk_mesh().payload().size();
      if (last) *last = Clock::now();
    }
  }
}

void BM_BrushRadius4EditToDecodedDeltas(benchmark::State& state) {
  test::ServerProcess server;
  client::Client c;
  c.connect("127.0.0.1", server.port(), 5s);
  c.handshake("bench", 5s);
  const world::TerrainGenerator gen(1);
  const int radius = 4;
  const world::ChunkCoord centre =
      world::chunk_of_voxel(0, static_cast<int>(std::floor(gen.height_at(0, 0))), 0);
  c.send(client::make_set_view(0, gen.height_at(0, 0), 0, radius));
  drain(c, 1000ms);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> xz(-60, 60);
  std::vector<double> us;
  uint64_t id = 0;
  for (auto _ : state) {
    const float x = xz(rng), z = xz(rng);
    ++id;
    const auto t0 = Clock::now();
    c.send(client::make_brush(id, x, gen.height_at(static_cast<int>(x), static_cast<int>(z)), z, 4,
                              0.8f, id % 2 == 0));
    std::set<std::tuple<int, int, int>> waiting;
    bool have_result = false;
    while (!have_result || !waiting.empty()) {
      auto m = c.receive(5s);
      if (!m) std::abort();
      if (m->has_edit_result()) {
        have_result = true;
        for (const auto& k : m->edit_result().changed_chunks()) {
          const int dx = k.x() - centre.x, dy = k.y() - centre.y, dz = k.z() - centre.z;
          if (dx * dx + dy * dy + dz * dz <= radius * radius)
            waiting.insert({k.x(), k.y(), k.z()});  // in view
        }
      } else if (m->has_chunk_mesh()) {
        if (c.apply(m->chunk_mesh())) std::abort();
        const auto& k = m->chunk_mesh().coord();
        waiting.erase({k.x(), k.y(), k.z()});
      }
    }
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  }
  std::sort(us.begin(), us.end());
  state.counters["p50_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[us.size() * 99 / 100];
  state.counters["max_us"] = us.back();
}
BENCHMARK(BM_BrushRadius4EditToDecodedDeltas)
    ->Iterations(500)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

void BM_FreshClientViewRadius8(benchmark::State& state) {
  for (auto _ : state) {
    test::ServerProcess server;  // a fresh world: generation included
    client::Client c;
    c.connect("127.0.0.1", server.port(), 5s);
    c.handshake("viewer", 5s);
    const world::TerrainGenerator gen(1);
    const auto t0 = Clock::now();
    c.send(client::make_set_view(16, gen.height_at(16, 16), 16, 8));
    Clock::time_point last = t0;
    size_t meshes = 0, bytes = 0;
    drain(c, 1500ms, &last, &meshes, &bytes);
    state.SetIterationTime(std::chrono::duration<double>(last - t0).count());
    state.counters["chunks_sent"] = static_cast<double>(meshes);
    state.counters["payload_KiB"] = static_cast<double>(bytes) / 1024;
    state.counters["bytes_per_chunk"] =
        static_cast<double>(bytes) / static_cast<double>(std::max<size_t>(meshes, 1));
  }
}
BENCHMARK(BM_FreshClientViewRadius8)->Iterations(3)->Unit(benchmark::kMillisecond)->UseManualTime();

}  // namespace

BENCHMARK_MAIN();
