// The world store's group commit, as the pipeline uses it: one durable transaction per
// batch of edits. Reports edits per second at each batch size (the rate one store can
// sustain) and the log's bytes on disk per edit. SQLite in a temporary world directory;
// PostgreSQL on a server this benchmark starts (tests/postgres_server.hpp).
//   build/bin/bench_store [--benchmark_filter=sqlite]
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <random>

#include "server/store/world_store.hpp"
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

void BM_AppendSqlite(benchmark::State& state) { append_batches(state, "sqlite"); }
void BM_AppendPostgres(benchmark::State& state) { append_batches(state, "postgresql"); }
BENCHMARK(BM_AppendSqlite)->Arg(1)->Arg(16)->Arg(64)->Arg(256)->UseRealTime()->MinTime(2);
BENCHMARK(BM_AppendPostgres)->Arg(1)->Arg(16)->Arg(64)->Arg(256)->UseRealTime()->MinTime(2);

}  // namespace

BENCHMARK_MAIN();
