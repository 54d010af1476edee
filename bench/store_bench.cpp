// The world store's group commit, as the pipeline uses it: one durable transaction per
// batch of edits. Reports edits per second at each batch size (the rate one store can
// sustain) and the log's bytes on disk per edit. SQLite in a temporary world directory;
// PostgreSQL on a server this benchmark starts (tests/postgres_server.hpp).
//   build/bin/bench_store [--benchmark_filter=sqlite]
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <random>

#include "server/store/chunk_codec.hpp"
#include "server/store/world_store.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/postgres_server.hpp"

namespace {

namespace fs = std::filesystem;
using namespace vox;

std::vector<world::Edit> random_edits(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-500, 500), r(1, 8);
  std::vector<world::Edit> out;
  for (size_t i = 0; i < n; ++i) {
    const world::Vec3 c{pos(rng), pos(rng) / 10, pos(rng)};
    if (i % 2)
      out.push_back(world::Explosion{c, r(rng), 1});
    else
      out.push_back(world::Brush{c, r(rng), 0.5f, false, std::nullopt});
  }
  return out;
}

std::unique_ptr<test::PostgresServer>& postgres() {
  static std::unique_ptr<test::PostgresServer> server;
  return server;
}

void append_batches(benchmark::State& state, const std::string& backend) {
  const size_t batch = static_cast<size_t>(state.range(0));
  static int n = 0;
  std::string where;
  fs::path dir;
  if (backend == "sqlite") {
    dir = fs::temp_directory_path() / ("voxel_store_bench_" + std::to_string(n++));
    fs::remove_all(dir);
    where = dir.string();
  } else {
    if (!postgres()) postgres() = std::make_unique<test::PostgresServer>();
    where = postgres()->create_database("bench" + std::to_string(n++));
  }
  auto store = store::open_world_store(where, {.seed = 1});
  const auto edits = random_edits(4096, 7);
  uint64_t seq = 1;
  std::vector<store::LoggedEdit> log(batch);
  for (auto _ : state) {
    for (size_t i = 0; i < batch; ++i)
      log[i] = {seq, 1764633600000, "", edits[(seq++) % edits.size()]};
    store->append_edits(log);
  }
  const store::WorldInfo info = store->info();
  state.counters["edits/s"] = benchmark::Counter(static_cast<double>(state.iterations() * batch),
                                                 benchmark::Counter::kIsRate);
  state.counters["bytes/edit"] =
      static_cast<double>(info.size_bytes) / static_cast<double>(info.logged_edits);
  if (!dir.empty()) fs::remove_all(dir);
}

// The log's size on disk per edit once SQLite has folded its WAL into the file: 100,000
// edits in batches of 64, the store closed, the file measured.
void BM_LogBytesPerEditSqlite(benchmark::State& state) {
  const auto edits = random_edits(4096, 9);
  for (auto _ : state) {
    const fs::path dir = fs::temp_directory_path() / "voxel_store_bench_size";
    fs::remove_all(dir);
    constexpr size_t kEdits = 100000, kBatch = 64;
    {
      auto store = store::open_world_store(dir.string(), {.seed = 1});
      std::vector<store::LoggedEdit> log;
      for (uint64_t seq = 1; seq <= kEdits; ++seq) {
        log.push_back({seq, 1764633600000 + static_cast<int64_t>(seq), "", edits[seq % 4096]});
        if (log.size() == kBatch || seq == kEdits) {
          store->append_edits(log);
          log.clear();
        }
      }
    }
    state.counters["bytes/edit"] =
        static_cast<double>(fs::file_size(dir / "world.sqlite")) / static_cast<double>(kEdits);
    fs::remove_all(dir);
  }
}
BENCHMARK(BM_LogBytesPerEditSqlite)->Iterations(1)->Unit(benchmark::kMillisecond);

// A checkpoint's work per chunk: compressing a surface chunk's samples (bytes: the record).
void BM_EncodeSurfaceChunk(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  const int32_t y = static_cast<int32_t>(gen.height_at(16, 16)) / world::kChunkSize;
  const world::Chunk chunk = gen.generate({0, y, 0});
  size_t bytes = 0;
  for (auto _ : state) bytes = store::encode_chunk(chunk).size();
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["chunks/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EncodeSurfaceChunk)->Unit(benchmark::kMicrosecond);

// A checkpoint's transaction: `range(0)` surface chunks of about 12.7 KB each, replaced
// again and again (as a busy world does), on SQLite.
void BM_CheckpointSqlite(benchmark::State& state) {
  const fs::path dir = fs::temp_directory_path() / "voxel_store_bench_checkpoint";
  fs::remove_all(dir);
  auto store = store::open_world_store(dir.string(), {.seed = 1});
  const world::TerrainGenerator gen(1);
  const int32_t y = static_cast<int32_t>(gen.height_at(16, 16)) / world::kChunkSize;
  const std::vector<uint8_t> samples = store::encode_chunk(gen.generate({0, y, 0}));
  std::vector<store::ChunkRecord> records;
  for (int64_t i = 0; i < state.range(0); ++i)
    records.push_back(
        {{static_cast<int32_t>(i % 100), y, static_cast<int32_t>(i / 100)}, 0, samples});
  uint64_t seq = 0;
  for (auto _ : state) {
    ++seq;
    for (auto& r : records) r.seq = seq;
    store->write_checkpoint(records, seq, seq);
  }
  state.counters["chunks/s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * state.range(0)), benchmark::Counter::kIsRate);
  fs::remove_all(dir);
}
BENCHMARK(BM_CheckpointSqlite)->Arg(64)->Arg(512)->UseRealTime()->Unit(benchmark::kMillisecond);

void BM_AppendSqlite(benchmark::State& state) { append_batches(state, "sqlite"); }
void BM_AppendPostgres(benchmark::State& state) { append_batches(state, "postgresql"); }
BENCHMARK(BM_AppendSqlite)->Arg(1)->Arg(16)->Arg(64)->Arg(256)->UseRealTime()->MinTime(2);
BENCHMARK(BM_AppendPostgres)->Arg(1)->Arg(16)->Arg(64)->Arg(256)->UseRealTime()->MinTime(2);

}  // namespace

BENCHMARK_MAIN();
