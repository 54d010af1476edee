// Mesh codec benchmarks: bytes per triangle against raw, raw + zstd, quantised + zstd and
// meshoptimizer + zstd on the same chunks; encode/decode time; delta size after a brush.
// Run: build/bin/bench_codec (see docs/PERFORMANCE.md).
#include <benchmark/benchmark.h>
#include <meshoptimizer.h>
#include <zstd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <random>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/terrain_generator.hpp"

namespace {

using namespace vox;

struct Sample {
  world::ChunkCoord coord;
  mesh::ChunkMesh mesh;
  proto::Bytes encoding;
};

world::ChunkMap& world_map() {
  static world::ChunkMap map = [] {
    const world::TerrainGenerator gen(1);
    world::ChunkMap m;
    for (int z = -9; z <= 8; ++z)
      for (int y = -4; y <= 2; ++y)
        for (int x = -9; x <= 8; ++x) m.insert({x, y, z}, gen.generate({x, y, z}));
    return m;
  }();
  return map;
}

Sample mesh_chunk_at(const world::ChunkMap& map, world::ChunkCoord c) {
  static mesh::PaddedBlock block;
  static mesh::MeshScratch topology;
  static proto::CodecScratch scratch;
  Sample s{c, {}, {}};
  mesh::gather_padded_block(map, c, block);
  mesh::mesh_chunk(block, topology, s.mesh);
  proto::encode_mesh(s.mesh, topology, block.cells, scratch, s.encoding);
  return s;
}

// Every chunk the surface crosses in the 16x5x16-chunk area of seed 1.
const std::vector<Sample>& samples() {
  static const std::vector<Sample> all = [] {
    std::vector<Sample> out;
    for (int z = -8; z < 8; ++z)
      for (int y = -3; y < 2; ++y)
        for (int x = -8; x < 8; ++x) {
          Sample s = mesh_chunk_at(world_map(), {x, y, z});
          if (!s.mesh.empty()) out.push_back(std::move(s));
        }
    return out;
  }();
  return all;
}

size_t zstd_size(const void* data, size_t n, int level) {
  std::vector<uint8_t> out(ZSTD_compressBound(n));
  return ZSTD_compress(out.data(), out.size(), data, n, level);
}

uint16_t quantise(float c) { return static_cast<uint16_t>(std::lround(c * proto::kFractionSteps)); }

struct BaselineVertex {  // 12 bytes: meshoptimizer's vertex codec needs a multiple of 4
  uint16_t x, y, z;
  uint8_t nu, nv, material, pad[3];
};

// meshoptimizer: vertex cache + fetch optimisation, index and vertex codecs, then zstd.
size_t meshopt_size(const mesh::ChunkMesh& m, int level) {
  std::vector<BaselineVertex> vertices(m.vertex_count());
  for (size_t v = 0; v < vertices.size(); ++v) {
    const auto n = proto::encode_normal(m.normals[v]);
    vertices[v] = {quantise(m.positions[v].x),
                   quantise(m.positions[v].y),
                   quantise(m.positions[v].z),
                   n[0],
                   n[1],
                   m.materials[v],
                   {0, 0, 0}};
  }
  std::vector<unsigned> indices(m.indices.begin(), m.indices.end());
  meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), vertices.size());
  meshopt_optimizeVertexFetch(vertices.data(), indices.data(), indices.size(), vertices.data(),
                              vertices.size(), sizeof(BaselineVertex));
  std::vector<uint8_t> ib(meshopt_encodeIndexBufferBound(indices.size(), vertices.size()));
  ib.resize(meshopt_encodeIndexBuffer(ib.data(), ib.size(), indices.data(), indices.size()));
  std::vector<uint8_t> vb(meshopt_encodeVertexBufferBound(vertices.size(), sizeof(BaselineVertex)));
  vb.resize(meshopt_encodeVertexBuffer(vb.data(), vb.size(), vertices.data(), vertices.size(),
                                       sizeof(BaselineVertex)));
  ib.insert(ib.end(), vb.begin(), vb.end());
  return zstd_size(ib.data(), ib.size(), level);
}

void BM_SizeComparison(benchmark::State& state) {
  const int level = proto::kDefaultZstdLevel;
  size_t triangles = 0, raw = 0, raw_zstd = 0, quant_zstd = 0, meshopt = 0, ours = 0;
  proto::ZstdCodec zstd;
  std::vector<uint8_t> frame;
  for (auto _ : state) {
    triangles = raw = raw_zstd = quant_zstd = meshopt = ours = 0;
    for (const Sample& s : samples()) {
      const mesh::ChunkMesh& m = s.mesh;
      triangles += m.triangle_count();
      std::vector<uint8_t> flat;
      auto append = [&flat](const void* p, size_t n) {
        flat.insert(flat.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
      };
      append(m.positions.data(), m.positions.size() * 12);
      append(m.normals.data(), m.normals.size() * 12);
      append(m.materials.data(), m.materials.size());
      append(m.indices.data(), m.indices.size() * 4);
      raw += flat.size();
      raw_zstd += zstd_size(flat.data(), flat.size(), level);
      std::vector<uint8_t>
          q;  // 8-byte vertices (3 x u16 position, 2 x u8 normal), material, u16 indices
      for (size_t v = 0; v < m.vertex_count(); ++v) {
        const uint16_t p[3] = {quantise(m.positions[v].x), quantise(m.positions[v].y),
                               quantise(m.positions[v].z)};
        const auto n = proto::encode_normal(m.normals[v]);
        q.insert(q.end(), reinterpret_cast<const uint8_t*>(p),
                 reinterpret_cast<const uint8_t*>(p) + 6);
        q.push_back(n[0]);
        q.push_back(n[1]);
      }
      q.insert(q.end(), m.materials.begin(), m.materials.end());
      for (uint32_t i : m.indices) {
        q.push_back(static_cast<uint8_t>(i));
        q.push_back(static_cast<uint8_t>(i >> 8));
      }
      quant_zstd += zstd_size(q.data(), q.size(), level);
      meshopt += meshopt_size(m, level);
      zstd.compress(s.encoding, {}, frame);
      ours += frame.size();
    }
  }
  const double t = static_cast<double>(triangles);
  state.counters["chunks"] = static_cast<double>(samples().size());
  state.counters["tris_per_chunk"] = t / static_cast<double>(samples().size());
  state.counters["B_per_tri_raw"] = static_cast<double>(raw) / t;
  state.counters["B_per_tri_raw_zstd"] = static_cast<double>(raw_zstd) / t;
  state.counters["B_per_tri_quant_zstd"] = static_cast<double>(quant_zstd) / t;
  state.counters["B_per_tri_meshopt_zstd"] = static_cast<double>(meshopt) / t;
  state.counters["B_per_tri_voxeld"] = static_cast<double>(ours) / t;
}
BENCHMARK(BM_SizeComparison)->Iterations(1)->Unit(benchmark::kMillisecond);

// Median over the chunks of each chunk's best of 5 runs of fn(i): the per-chunk cost
// with that chunk's data in cache (the same method as the mesher's median).
template <class Fn>
void per_chunk_median(benchmark::State& state, size_t n, Fn&& fn) {
  std::vector<double> best(n, 1e9);
  for (size_t i = 0; i < n; ++i)
    for (int r = 0; r < 5; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      fn(i);
      best[i] = std::min(
          best[i],
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    }
  std::sort(best.begin(), best.end());
  state.counters["median_us"] = best[n / 2];
  state.counters["p90_us"] = best[n * 9 / 10];
}

void BM_EncodeAndCompress(benchmark::State& state) {
  const auto& all = samples();
  mesh::PaddedBlock block;
  proto::CodecScratch scratch;
  proto::ZstdCodec zstd;
  proto::Bytes encoding;
  std::vector<uint8_t> frame;
  // Topology for every sample is rebuilt once up front, so the loop times encoding only.
  std::vector<mesh::MeshScratch> topologies(all.size());
  for (size_t i = 0; i < all.size(); ++i) {
    mesh::gather_padded_block(world_map(), all[i].coord, block);
    mesh::ChunkMesh m;
    mesh::mesh_chunk(block, topologies[i], m);
  }
  size_t i = 0;
  for (auto _ : state) {
    proto::encode_mesh(all[i].mesh, topologies[i], {32, 32, 32}, scratch, encoding);
    zstd.compress(encoding, {}, frame);
    benchmark::DoNotOptimize(frame.data());
    i = (i + 1) % all.size();
  }
  per_chunk_median(state, all.size(), [&](size_t k) {
    proto::encode_mesh(all[k].mesh, topologies[k], {32, 32, 32}, scratch, encoding);
    zstd.compress(encoding, {}, frame);
  });
}
BENCHMARK(BM_EncodeAndCompress)->Unit(benchmark::kMicrosecond);

void BM_DecompressAndDecode(benchmark::State& state) {
  const auto& all = samples();
  proto::ZstdCodec zstd;
  std::vector<std::vector<uint8_t>> frames(all.size());
  for (size_t i = 0; i < all.size(); ++i) zstd.compress(all[i].encoding, {}, frames[i]);
  proto::CodecScratch scratch;
  mesh::ChunkMesh m;
  mesh::Buffer<uint8_t> encoding;
  size_t i = 0;
  for (auto _ : state) {
    zstd.decompress_into(frames[i], {}, proto::DecodeLimits{}.max_encoding_bytes, encoding);
    auto error = proto::decode_mesh(encoding, {}, scratch, m);
    benchmark::DoNotOptimize(error);
    benchmark::DoNotOptimize(m.indices.data());
    i = (i + 1) % all.size();
  }
  per_chunk_median(state, all.size(), [&](size_t k) {
    zstd.decompress_into(frames[k], {}, proto::DecodeLimits{}.max_encoding_bytes, encoding);
    (void)proto::decode_mesh(encoding, {}, scratch, m);
  });
}
BENCHMARK(BM_DecompressAndDecode)->Unit(benchmark::kMicrosecond);

// Brush of radius 2 at a surface point at least 3 samples inside a chunk: delta size as
// a share of the new full message, median over positions.
void BM_DeltaAfterBrushRadius2(benchmark::State& state) {
  const world::TerrainGenerator gen(1);
  std::mt19937 rng(5);
  proto::ZstdCodec zstd(proto::kDefaultZstdLevel, static_cast<int>(state.range(0)));
  std::vector<double> ratios;
  size_t delta_bytes = 0, full_bytes = 0;
  for (auto _ : state) {
    for (int k = 0; k < 2000; ++k) {
      const float x = static_cast<float>(-8 * 32 + static_cast<int>(rng() % (16 * 32)));
      const float z = static_cast<float>(-8 * 32 + static_cast<int>(rng() % (16 * 32)));
      const float y = gen.height_at(static_cast<int>(x), static_cast<int>(z));
      const int lx = world::floor_mod(static_cast<int>(x), 32),
                ly = world::floor_mod(static_cast<int>(y), 32),
                lz = world::floor_mod(static_cast<int>(z), 32);
      if (lx < 3 || lx > 28 || ly < 3 || ly > 28 || lz < 3 || lz > 28) continue;
      const world::ChunkCoord c =
          world::chunk_of_voxel(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z));
      world::ChunkMap& map = world_map();
      const Sample before = mesh_chunk_at(map, c);
      world::Chunk saved = *map.find(c);
      const world::Edit edit =
          world::Brush{{x + 0.3f, y, z + 0.6f}, 2, 0.8f, (k % 2) == 1, std::nullopt};
      world::apply_edit(edit, c, *map.find(c), nullptr);
      const Sample after = mesh_chunk_at(map, c);
      map.insert(c, std::move(saved));
      if (after.encoding == before.encoding) continue;
      std::vector<uint8_t> full, delta;
      zstd.compress(after.encoding, {}, full);
      zstd.compress(after.encoding, before.encoding, delta);
      ratios.push_back(static_cast<double>(delta.size()) / static_cast<double>(full.size()));
      delta_bytes += delta.size();
      full_bytes += full.size();
    }
  }
  std::sort(ratios.begin(), ratios.end());
  state.counters["edits"] = static_cast<double>(ratios.size());
  state.counters["median_delta_share"] = ratios[ratios.size() / 2];
  state.counters["p90_delta_share"] = ratios[ratios.size() * 9 / 10];
  state.counters["mean_delta_bytes"] =
      static_cast<double>(delta_bytes) / static_cast<double>(ratios.size());
  state.counters["mean_full_bytes"] =
      static_cast<double>(full_bytes) / static_cast<double>(ratios.size());
}
BENCHMARK(BM_DeltaAfterBrushRadius2)
    ->Arg(3)
    ->Arg(5)
    ->Arg(7)
    ->Arg(9)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace

namespace {

// The parts: zstd alone at several levels, and the codec without zstd.
void BM_ZstdCompressLevel(benchmark::State& state) {
  const auto& all = samples();
  proto::ZstdCodec zstd(static_cast<int>(state.range(0)));
  std::vector<uint8_t> frame;  // full messages at this level
  size_t i = 0, bytes = 0, tris = 0;
  for (auto _ : state) {
    zstd.compress(all[i].encoding, {}, frame);
    bytes += frame.size();
    tris += all[i].mesh.triangle_count();
    i = (i + 1) % all.size();
  }
  state.counters["B_per_tri"] = static_cast<double>(bytes) / static_cast<double>(tris);
}
BENCHMARK(BM_ZstdCompressLevel)
    ->Arg(-5)
    ->Arg(-1)
    ->Arg(1)
    ->Arg(3)
    ->Arg(6)
    ->Arg(9)
    ->Unit(benchmark::kMicrosecond);

void BM_ZstdDecompress(benchmark::State& state) {
  const auto& all = samples();
  proto::ZstdCodec zstd(static_cast<int>(state.range(0)));
  std::vector<std::vector<uint8_t>> frames(all.size());
  for (size_t i = 0; i < all.size(); ++i) zstd.compress(all[i].encoding, {}, frames[i]);
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(zstd.decompress(frames[i], {}, 1 << 22));
    i = (i + 1) % all.size();
  }
}
BENCHMARK(BM_ZstdDecompress)->Arg(-5)->Arg(-1)->Arg(1)->Arg(3)->Unit(benchmark::kMicrosecond);

void BM_DecodeOnly(benchmark::State& state) {
  const auto& all = samples();
  proto::CodecScratch scratch;
  mesh::ChunkMesh m;
  size_t i = 0;
  for (auto _ : state) {
    auto error = proto::decode_mesh(all[i].encoding, {}, scratch, m);
    benchmark::DoNotOptimize(error);
    benchmark::DoNotOptimize(m.indices.data());
    i = (i + 1) % all.size();
  }
}
BENCHMARK(BM_DecodeOnly)->Unit(benchmark::kMicrosecond);

}  // namespace

namespace {
// Decoding one chunk over and over (everything in cache): the codec's own cost.
void BM_DecodeOnlyWarm(benchmark::State& state) {
  const auto& all = samples();
  const auto& s = *std::max_element(all.begin(), all.end(), [&](const Sample& a, const Sample& b) {
    return std::abs(static_cast<long>(a.mesh.triangle_count()) - 1544) >
           std::abs(static_cast<long>(b.mesh.triangle_count()) - 1544);
  });
  proto::CodecScratch scratch;
  mesh::ChunkMesh m;
  for (auto _ : state) {
    auto error = proto::decode_mesh(s.encoding, {}, scratch, m);
    benchmark::DoNotOptimize(error);
  }
  state.counters["triangles"] = static_cast<double>(s.mesh.triangle_count());
}
BENCHMARK(BM_DecodeOnlyWarm)->Unit(benchmark::kMicrosecond);
}  // namespace

BENCHMARK_MAIN();
