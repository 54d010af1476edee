// What a far view costs: a player's whole view meshed, encoded and compressed
// as the server would send it, once with today's level-0 chunks to radius 8 and once as a
// level-of-detail layout reaching 2,048 voxels (levels 0..6, level 0 near the eye), on one
// thread. Counters: meshes with a surface, triangles, bytes on the wire.
// Run: build/bin/bench_lod_view (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <span>
#include <stdexcept>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/lod_layout.hpp"
#include "server/world/lod_view.hpp"
#include "server/world/overlay_sampler.hpp"
#include "server/world/terrain_generator.hpp"
#include "server/world/terrain_sampler.hpp"

namespace {

using namespace vox;

const world::TerrainGenerator& generator() {
  static const world::TerrainGenerator gen(1);
  return gen;
}

std::array<double, 3> eye() {
  return {40.5, static_cast<double>(generator().height_at(40, -20)) + 2.0, -20.5};
}

struct ViewCost {
  size_t meshes = 0, triangles = 0, bytes = 0;
};

void report(benchmark::State& state, const ViewCost& cost) {
  state.counters["meshes"] = static_cast<double>(cost.meshes);
  state.counters["triangles"] = static_cast<double>(cost.triangles);
  state.counters["bytes"] = static_cast<double>(cost.bytes);
}

// A level-of-detail chunk meshed, encoded (format 2) and compressed, in full or as a delta
// against `base`; the buffers reused from chunk to chunk.
struct LodWork {
  world::TerrainSampler sampler{generator()};
  mesh::LodBlock block;
  mesh::LodScratch lod;
  mesh::ChunkMesh mesh;
  proto::CodecScratch scratch;
  proto::ZstdCodec zstd;
  proto::Bytes encoding, frame;

  // Returns whether the chunk has a surface (then `frame` holds its payload).
  bool make(const world::LodChunk& c, world::LodSeams seams, std::span<const uint8_t> base = {}) {
    mesh::gather_lod_block(sampler, c, seams, block);
    mesh::mesh_lod_chunk(block, lod, mesh);
    if (mesh.empty()) return false;
    proto::encode_lod_mesh(mesh, lod, scratch, encoding);
    zstd.compress(encoding, base, frame);
    return true;
  }
};

// Today's view: every level-0 chunk within radius 8 (Euclidean, in chunks) of the eye's
// chunk, generated, meshed (format 1) and compressed as full messages.
void BM_Radius8LevelZeroView(benchmark::State& state) {
  const auto e = eye();
  const world::ChunkCoord centre = world::chunk_of_voxel(static_cast<int32_t>(std::floor(e[0])),
                                                         static_cast<int32_t>(std::floor(e[1])),
                                                         static_cast<int32_t>(std::floor(e[2])));
  constexpr int r = 8;
  mesh::PaddedBlock block;
  mesh::MeshScratch topology;
  mesh::ChunkMesh mesh;
  proto::CodecScratch scratch;
  proto::ZstdCodec zstd;
  proto::Bytes encoding, frame;
  ViewCost cost;
  for (auto _ : state) {
    cost = {};
    world::ChunkMap map;  // the server generates each chunk once, the margin too
    for (int z = -r - 1; z <= r + 1; ++z)
      for (int y = -r - 1; y <= r + 1; ++y)
        for (int x = -r - 1; x <= r + 1; ++x) {
          const world::ChunkCoord c = centre.offset(x, y, z);
          map.insert(c, generator().generate(c));
        }
    for (int z = -r; z <= r; ++z)
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
          if (x * x + y * y + z * z > r * r) continue;
          mesh::gather_padded_block(map, centre.offset(x, y, z), block);
          mesh::mesh_chunk(block, topology, mesh);
          if (mesh.empty()) continue;
          proto::encode_mesh(mesh, topology, block.cells, scratch, encoding);
          zstd.compress(encoding, {}, frame);
          ++cost.meshes;
          cost.triangles += mesh.triangle_count();
          cost.bytes += frame.size();
        }
  }
  report(state, cost);
}
BENCHMARK(BM_Radius8LevelZeroView)->Unit(benchmark::kMillisecond)->Iterations(3);

// A level-of-detail view to 2,048 voxels: levels 0..6, 3x3x3 level-6 chunks around the
// eye, each split while the eye is nearer than split_x10 / 10 times its side (level-1
// chunks: near_split_x10 / 10; 2.0 keeps level 0 within 4 chunks). Level-0 chunks are
// generated once each into a chunk map, as the server does. Level-0 chunks come from
// the generator like today's; coarser ones from the generator at their own spacing, with
// their seams. Format 2 for levels >= 1.
void BM_LodView2048(benchmark::State& state) {
  const double split = static_cast<double>(state.range(0)) / 10.0;
  const double near_split = static_cast<double>(state.range(1)) / 10.0;
  world::LodLayout layout(
      {.levels = 7, .top_radius = 1, .split_distance = split, .near_split_distance = near_split});
  layout.update(eye());
  LodWork w;
  ViewCost cost;
  std::array<size_t, 7> per_level{};
  for (auto _ : state) {
    cost = {};
    per_level = {};
    world::ChunkMap map;  // level 0 as the server has it: each chunk generated once
    for (const world::LodChunk& c : layout.chunks()) {
      if (c.level != 0) continue;
      world::for_each_chunk_in(c.c.offset(-1, -1, -1), c.c.offset(1, 1, 1),
                               [&](world::ChunkCoord n) {
                                 if (map.find(n) == nullptr) map.insert(n, generator().generate(n));
                               });
    }
    for (const world::LodChunk& c : layout.chunks()) {
      if (c.level == 0) {
        mesh::gather_padded_block(map, c.c, w.block.coarse);
        mesh::mesh_chunk(w.block.coarse, w.lod.mc, w.mesh);
        if (w.mesh.empty()) continue;
        proto::encode_mesh(w.mesh, w.lod.mc, w.block.coarse.cells, w.scratch, w.encoding);
        w.zstd.compress(w.encoding, {}, w.frame);
      } else if (!w.make(c, layout.seams(c))) {
        continue;
      }
      ++cost.meshes;
      ++per_level[static_cast<size_t>(c.level)];
      cost.triangles += w.mesh.triangle_count();
      cost.bytes += w.frame.size();
    }
  }
  report(state, cost);
  state.counters["layout_chunks"] = static_cast<double>(layout.chunks().size());
  for (size_t k = 0; k < per_level.size(); ++k)
    state.counters["meshes_l" + std::to_string(k)] = static_cast<double>(per_level[k]);
}
BENCHMARK(BM_LodView2048)
    ->Args({10, 10})
    ->Args({10, 20})
    ->Args({15, 20})
    ->Args({20, 20})
    ->ArgNames({"split_x10", "near_split_x10"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// A coarse chunk re-meshed after an edit, as the server's LOD stage does it: its samples
// gathered once for the union of the seams variants players want (the generated grids
// from a warm cache, as the stage keeps them), its regular vertices made once, then each
// variant meshed, encoded and compressed. The level-1 chunks of the near-split-2.0 view
// with a surface, four variants each (no seams, -x, +z, -x and +z). Counter: variants/s.
// shared_vertices:0 makes the vertices again for each variant (as before they were shared).
void BM_LodRemeshVariants(benchmark::State& state) {
  world::LodLayout layout(
      {.levels = 7, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0});
  layout.update(eye());
  LodWork w;
  world::GridCache grids(size_t{256} << 20);
  const world::OverlaySampler::ModifiedSet none;
  const world::OverlaySampler sampler(
      generator(), none,
      [](world::ChunkCoord) -> const world::Chunk& { throw std::logic_error("unmodified"); },
      &grids);
  const world::LodSeams gathered{world::kMinusX | world::kPlusZ, 0};
  std::vector<world::LodChunk> chunks;
  for (const world::LodChunk& c : layout.chunks()) {
    if (c.level != 1) continue;
    mesh::gather_lod_block(sampler, c, gathered, w.block);  // warms the cache
    mesh::mesh_lod_chunk(w.block, w.lod, w.mesh);
    if (!w.mesh.empty()) chunks.push_back(c);
  }
  const world::LodSeams variants[] = {
      {0, 0}, {world::kMinusX, 0}, {world::kPlusZ, 0}, {world::kMinusX | world::kPlusZ, 0}};
  const bool shared = state.range(0) != 0;
  size_t meshed = 0;
  uint64_t pass = 0;
  for (auto _ : state) {
    for (const world::LodChunk& c : chunks) {
      mesh::gather_lod_block(sampler, c, gathered, w.block);
      if (shared) mesh::mesh_lod_vertices(w.block, w.lod);
      ++pass;
      for (const world::LodSeams s : variants) {
        w.block.seams = world::normalized(s);
        if (shared)
          mesh::mesh_lod_variant(w.block, w.lod, w.mesh);
        else
          mesh::mesh_lod_chunk(w.block, w.lod, w.mesh);  // vertices made again per variant
        proto::encode_lod_mesh(w.mesh, w.lod, w.scratch, w.encoding, shared ? pass : 0);
        w.zstd.compress(w.encoding, {}, w.frame);
        ++meshed;
      }
    }
  }
  state.counters["variants"] =
      benchmark::Counter(static_cast<double>(meshed), benchmark::Counter::kIsRate);
  state.counters["chunks"] = static_cast<double>(chunks.size());
}
BENCHMARK(BM_LodRemeshVariants)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("shared_vertices")
    ->Unit(benchmark::kMillisecond);

// One level's chunks of the view the load tester's players hold (split 1.0, level 0 within
// 4 chunks), each made as a new mesh is: its samples gathered with its seams, then (work:1)
// meshed, encoded and compressed. Where a first view's time goes, level by level.
// Counters: chunks of the level, of them with a surface, and the time per chunk.
void BM_LodChunksOfLevel(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  const bool whole = state.range(1) != 0;
  world::LodLayout layout(
      {.levels = 7, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0});
  layout.update(eye());
  std::vector<world::LodChunk> chunks;
  for (const world::LodChunk& c : layout.chunks())
    if (c.level == level) chunks.push_back(c);
  LodWork w;
  size_t surfaced = 0;
  for (auto _ : state) {
    surfaced = 0;
    for (const world::LodChunk& c : chunks) {
      if (whole) {
        surfaced += w.make(c, layout.seams(c)) ? 1 : 0;
      } else {
        mesh::gather_lod_block(w.sampler, c, layout.seams(c), w.block);
        benchmark::DoNotOptimize(w.block.coarse.density[0]);
      }
    }
  }
  state.counters["chunks"] = static_cast<double>(chunks.size());
  if (whole) state.counters["surfaced"] = static_cast<double>(surfaced);
  state.counters["per_chunk_us"] = benchmark::Counter(
      static_cast<double>(chunks.size()) * 1e-6,
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_LodChunksOfLevel)
    ->ArgsProduct({{1, 2, 3, 4, 5, 6}, {0, 1}})
    ->ArgNames({"level", "work"})
    ->Unit(benchmark::kMillisecond);

// What a walking player's SetViews cost the server's network thread: the view of the
// near-split-2.0 layout updated every 2 voxels along a 2,048-voxel walk (most updates are
// within the settled margin; the others lay the layout out again and diff it).
void BM_LodViewUpdatesAlongAWalk(benchmark::State& state) {
  size_t changed = 0;
  for (auto _ : state) {
    world::LodView view(
        {.levels = 7, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0});
    auto e = eye();
    changed = 0;
    for (double walked = 0; walked <= 2048.0; walked += 2.0) {
      e[0] = 40.5 + walked;
      const world::LodViewChange change = view.update(e);
      changed += change.send.empty() && change.unload.empty() ? 0 : 1;
    }
  }
  state.counters["changed_updates"] = static_cast<double>(changed);
}
BENCHMARK(BM_LodViewUpdatesAlongAWalk)->Unit(benchmark::kMillisecond);

// A player walking 512 voxels along x at the surface, 4 voxels per update (the layout of the
// near-split-2.0 view): what the changes cost on the wire. A chunk the client holds with
// other seams is sent as a zstd delta against its previous encoding (PROTOCOL §3); a new
// chunk in full. Counters: bytes per voxel walked, of them for seam changes, chunks sent.
void BM_LodWalk(benchmark::State& state) {
  LodWork w;
  size_t bytes = 0, seam_bytes = 0, sent = 0, resent = 0;
  constexpr double kWalk = 512.0, kStep = 4.0;
  for (auto _ : state) {
    bytes = seam_bytes = sent = resent = 0;
    world::LodView view(
        {.levels = 7, .top_radius = 1, .split_distance = 1.0, .near_split_distance = 2.0});
    std::map<world::LodChunk, proto::Bytes> held;  // the client's encodings
    auto e = eye();
    view.update(e);  // the first view is BM_LodView2048's; count the walk only
    for (const auto& [c, seams] : view.held()) held[c];
    for (double walked = kStep; walked <= kWalk; walked += kStep) {
      e[0] += kStep;
      e[1] = static_cast<double>(generator().height_at(static_cast<int32_t>(e[0]), -20)) + 2.0;
      const world::LodViewChange change = view.update(e);
      for (const world::LodChunk& c : change.unload) held.erase(c);
      for (const auto& [c, seams] : change.send) {
        if (c.level == 0) {
          held[c];  // level 0 streams as today (counted by the load test, not here)
          continue;
        }
        auto it = held.find(c);
        const bool delta = it != held.end() && !it->second.empty();
        if (!w.make(c, seams,
                    delta ? std::span<const uint8_t>(it->second) : std::span<const uint8_t>{}))
          w.encoding.clear();  // no surface: the client holds an empty mesh
        const size_t sent_bytes = w.encoding.empty() ? 0 : w.frame.size();
        bytes += sent_bytes;
        ++sent;
        if (it != held.end()) {
          seam_bytes += sent_bytes;
          ++resent;
        }
        held[c] = w.encoding;
      }
    }
  }
  state.counters["bytes_per_voxel"] = static_cast<double>(bytes) / kWalk;
  state.counters["seam_bytes_per_voxel"] = static_cast<double>(seam_bytes) / kWalk;
  state.counters["chunks_sent"] = static_cast<double>(sent);
  state.counters["seam_resends"] = static_cast<double>(resent);
}
BENCHMARK(BM_LodWalk)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
