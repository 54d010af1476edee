// Builds a durable world for the restart benchmark (bench/scripts/restart_run.sh): `edits`
// explosions and brushes at the surface over a square of about `chunks` chunk columns
// around the origin, through the real pipeline and its store (group commit, checkpoints,
// eviction), as a server would have made it. Prints the world's figures and the rate.
//
//   build/bin/bench_make_world WORLD [--edits N] [--chunks M] [--seed S] [--crash]
//
// WORLD: a directory (SQLite), a postgresql:// URI, or `postgres` (a PostgreSQL server this
// program starts in a temporary directory, tests/postgres_server.hpp, and stops). --crash: after
// the last edit is durable, exits at once (no final checkpoint, as kill -9 would): a restart
// replays the log since the last checkpoint.
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "tests/postgres_server.hpp"

namespace {

using namespace vox;

struct Options {
  std::string where;
  uint64_t edits = 100000, chunks = 10000, seed = 1;
  bool crash = false;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> uint64_t {
      if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
      return std::stoull(argv[++i]);
    };
    if (a == "--edits") {
      o.edits = value();
    } else if (a == "--chunks") {
      o.chunks = value();
    } else if (a == "--seed") {
      o.seed = value();
    } else if (a == "--crash") {
      o.crash = true;
    } else if (o.where.empty() && !a.starts_with("--")) {
      o.where = a;
    } else {
      throw std::runtime_error("unknown argument " + a);
    }
  }
  if (o.where.empty() || o.chunks == 0) throw std::runtime_error("usage: see bench/make_world.cpp");
  if (o.crash && o.where == "postgres")
    throw std::runtime_error("--crash would leave the temporary PostgreSQL server running");
  return o;
}

// Edit i lands in column i % columns of a side x side square centred on the origin.
world::Edit edit_number(uint64_t i, uint64_t side, const world::TerrainGenerator& gen,
                        std::mt19937& rng) {
  const uint64_t column = i % (side * side);
  const int32_t cx = static_cast<int32_t>(column % side) - static_cast<int32_t>(side / 2);
  const int32_t cz = static_cast<int32_t>(column / side) - static_cast<int32_t>(side / 2);
  std::uniform_int_distribution<int> in_chunk(4, 27);
  const int32_t x = cx * world::kChunkSize + in_chunk(rng);
  const int32_t z = cz * world::kChunkSize + in_chunk(rng);
  const world::Vec3 c{static_cast<float>(x), gen.height_at(x, z), static_cast<float>(z)};
  if (i % 2) return world::Explosion{c, 3, 0.6f};
  return world::Brush{c, 3, 0.5f, true, std::nullopt};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_make_world: %s\n", e.what());
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  std::unique_ptr<test::PostgresServer> postgres;
  if (o.where == "postgres") {
    postgres = std::make_unique<test::PostgresServer>();
    o.where = postgres->create_database("make_world");
  }
  auto store = store::open_world_store(o.where, {.seed = o.seed});
  auto cp = store::open_world_store(o.where, {.seed = o.seed, .record_start = false});
  pipeline::PipelineConfig config{.seed = o.seed,
                                  .evict_after = std::chrono::seconds(2),
                                  .max_memory = size_t{1536} << 20,
                                  .store = store.get(),
                                  .checkpoint_store = cp.get()};
  // Checkpoints as they go: how many chunks each took and how long.
  std::mutex cp_mutex;
  size_t cp_chunks_max = 0;
  double cp_seconds_max = 0, cp_seconds_total = 0;
  pipeline::PipelineObserver observer{.checkpoint = [&](double s, size_t chunks, size_t, bool) {
    std::lock_guard lock(cp_mutex);
    cp_chunks_max = std::max(cp_chunks_max, chunks);
    cp_seconds_max = std::max(cp_seconds_max, s);
    cp_seconds_total += s;
  }};
  pipeline::WorldPipeline p(config, observer);
  const world::TerrainGenerator gen(o.seed);
  const uint64_t side = static_cast<uint64_t>(std::ceil(std::sqrt(double(o.chunks))));
  std::mt19937 rng(20261202);
  std::mutex mutex;
  std::condition_variable cv;
  uint64_t in_flight = 0, refused = 0, held_back = 0;
  std::deque<world::Edit> retry;     // held back (SERVER_BUSY: the log awaits a checkpoint)
  constexpr uint64_t kWindow = 512;  // edits queued at once
  const auto start = std::chrono::steady_clock::now();
  auto submit = [&](world::Edit edit) {
    p.submit(edit, [&, edit](const pipeline::EditResult& r) {
      std::lock_guard lock(mutex);
      --in_flight;
      if (r.reason == world::RefusalReason::kServerBusy) {
        ++held_back;
        retry.push_back(edit);
      } else {
        refused += r.accepted ? 0 : 1;
      }
      cv.notify_all();
    });
  };
  for (uint64_t i = 0;;) {
    std::optional<world::Edit> again;
    {
      std::unique_lock lock(mutex);
      cv.wait(lock, [&] { return in_flight < kWindow; });
      if (!retry.empty()) {
        again = retry.front();
        retry.pop_front();
      } else if (i == o.edits) {
        if (in_flight == 0) break;
        cv.wait(lock, [&] { return in_flight == 0 || !retry.empty(); });
        continue;
      }
      ++in_flight;
    }
    if (again) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // the checkpoint's turn
      submit(*again);
    } else {
      submit(edit_number(i++, side, gen, rng));
    }
  }
  const double took =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const pipeline::PipelineStats s = p.stats();
  std::printf(
      "%llu edits (%llu refused, %llu held back and resent) in %.1f s: %.0f edits/s; %llu "
      "checkpoints (largest %zu chunks, longest %.0f ms, %.1f s in all)\n",
      static_cast<unsigned long long>(o.edits), static_cast<unsigned long long>(refused),
      static_cast<unsigned long long>(held_back), took, double(o.edits) / took,
      static_cast<unsigned long long>(s.checkpoints), cp_chunks_max, cp_seconds_max * 1000,
      cp_seconds_total);
  if (o.crash) {
    std::fflush(stdout);
    std::_Exit(0);  // no final checkpoint: the log since the last one stays to replay
  }
  p.stop();
  const store::WorldInfo info = store->info();
  std::printf(
      "world: %llu modified chunks, %llu logged edits, checkpoint through %llu, %llu "
      "bytes on disk\n",
      static_cast<unsigned long long>(info.modified_chunks),
      static_cast<unsigned long long>(info.logged_edits),
      static_cast<unsigned long long>(info.checkpoint_seq),
      static_cast<unsigned long long>(info.size_bytes));
  return refused == 0 ? 0 : 1;
}
