// Writes mesh fixtures for the JavaScript client's bit-for-bit test (clients/web/README.md):
// for a handful of chunks, the C++ encoder's bytes (NAME.bin), them as the server's zstd
// full message (NAME.zst), and what the C++ decoder
// rebuilds from them (NAME.json: positions and normals as float32 bit patterns, materials,
// indices), plus manifest.json naming them and delta.json (a zstd full frame and a delta
// against another encoding, made by the server's codec).
//
//   voxel_mesh_fixtures OUT_DIR
//
// Chunks: terrain chunks of seed 3 in format 1 (one with dropped triangles if the search
// finds one), a sky chunk (empty), a chunk with every sample solid (full, no vertex), an
// odd-sized block (cells 5, 7, 3), the worked example of PROTOCOL §2.6, a random block
// whose rounding drops triangles, and level-of-detail chunks in format 2, with and without
// seams.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/lod_block.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/mesh/marching_cubes.hpp"
#include "server/mesh/padded_block.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/lod_layout.hpp"
#include "server/world/sample.hpp"
#include "server/world/terrain_generator.hpp"
#include "server/world/terrain_sampler.hpp"

namespace {

using namespace vox;
using proto::Bytes;

std::string out_dir;
std::vector<std::string> names;
std::vector<Bytes> frames;  // each fixture's zstd full frame, for --time

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

uint32_t u32_at(const Bytes& b, size_t at) {
  return b[at] | b[at + 1] << 8 | b[at + 2] << 16 | uint32_t{b[at + 3]} << 24;
}

std::string hex(const Bytes& b) {
  static const char* digits = "0123456789abcdef";
  std::string s;
  s.reserve(b.size() * 2);
  for (uint8_t c : b) {
    s += digits[c >> 4];
    s += digits[c & 15];
  }
  return s;
}

void write_file(const std::string& name, const std::string& text) {
  std::ofstream f(out_dir + "/" + name, std::ios::binary);
  f.write(text.data(), static_cast<std::streamsize>(text.size()));
  if (!f) {
    std::fprintf(stderr, "cannot write %s/%s\n", out_dir.c_str(), name.c_str());
    std::exit(1);
  }
}

// Writes NAME.bin and NAME.json: the C++ decoder's output for `encoding` (which must decode
// and give the mesher's indices).
void write_fixture(const std::string& name, const Bytes& encoding, const mesh::ChunkMesh& meshed,
                   int level, const std::string& note) {
  auto decoded = proto::decode_mesh(encoding);
  if (!decoded) {
    std::fprintf(stderr, "%s: the C++ decoder refuses it: %s\n", name.c_str(),
                 decoded.error().c_str());
    std::exit(1);
  }
  if (decoded->indices != meshed.indices) {
    std::fprintf(stderr, "%s: decoded indices differ from the mesher's\n", name.c_str());
    std::exit(1);
  }
  const mesh::ChunkMesh& m = *decoded;
  std::string j = "{\n";
  j += "\"name\": \"" + name + "\",\n";
  j += "\"note\": \"" + note + "\",\n";
  j += "\"format\": " + std::to_string(encoding[0]) + ",\n";
  j += "\"level\": " + std::to_string(level) + ",\n";
  j += "\"cells\": [" + std::to_string(encoding[1]) + ", " + std::to_string(encoding[2]) + ", " +
       std::to_string(encoding[3]) + "],\n";
  j += "\"dropped\": " + std::to_string(u32_at(encoding, 12)) + ",\n";
  j += "\"bytes\": " + std::to_string(encoding.size()) + ",\n";
  j += "\"vertex_count\": " + std::to_string(m.vertex_count()) + ",\n";
  j += "\"triangle_count\": " + std::to_string(m.triangle_count()) + ",\n";
  auto floats = [&](const char* key, const mesh::Buffer<mesh::Vec3f>& v) {
    j += std::string("\"") + key + "\": [";
    for (size_t i = 0; i < v.size(); ++i) {
      if (i) j += ",";
      j += std::to_string(bits(v[i].x)) + "," + std::to_string(bits(v[i].y)) + "," +
           std::to_string(bits(v[i].z));
    }
    j += "],\n";
  };
  floats("positions", m.positions);
  floats("normals", m.normals);
  j += "\"materials\": [";
  for (size_t i = 0; i < m.materials.size(); ++i) {
    if (i) j += ",";
    j += std::to_string(m.materials[i]);
  }
  j += "],\n\"indices\": [";
  for (size_t i = 0; i < m.indices.size(); ++i) {
    if (i) j += ",";
    j += std::to_string(m.indices[i]);
  }
  j += "]\n}\n";
  write_file(name + ".bin", std::string(encoding.begin(), encoding.end()));
  static proto::ZstdCodec codec;  // the server's full-message level
  Bytes frame;
  codec.compress(encoding, {}, frame);
  write_file(name + ".zst", std::string(frame.begin(), frame.end()));
  frames.push_back(frame);
  write_file(name + ".json", j);
  names.push_back(name);
  std::printf("%-24s format %d level %d: %zu bytes, %zu vertices, %zu triangles, %u dropped\n",
              name.c_str(), encoding[0], level, encoding.size(), m.vertex_count(),
              m.triangle_count(), u32_at(encoding, 12));
}

struct Meshed {
  mesh::ChunkMesh mesh;
  Bytes encoding;
};

Meshed mesh_block(const mesh::PaddedBlock& block) {
  static mesh::MeshScratch topology;
  static proto::CodecScratch scratch;
  Meshed e;
  mesh::mesh_chunk(block, topology, e.mesh);
  proto::encode_mesh(e.mesh, topology, block.cells, scratch, e.encoding);
  return e;
}

// A block of `cells` whose densities come from f(x, y, z) (block coordinates -1..33).
template <class F>
Meshed mesh_function(std::array<int, 3> cells, F&& f, world::Material material) {
  mesh::PaddedBlock block;
  block.cells = cells;
  for (int z = -1; z <= 33; ++z)
    for (int y = -1; y <= 33; ++y)
      for (int x = -1; x <= 33; ++x) {
        const int i = mesh::PaddedBlock::index(x, y, z);
        block.density[i] = f(x, y, z);
        block.material[i] = block.density[i] > 0 ? material : world::kAir;
      }
  return mesh_block(block);
}

}  // namespace

// --time: the C++ client's decode time per fixture, as the other clients' benchmarks
// report it (median of at least 30 runs and 300 ms, after a warm-up): zstd, then the
// decoder with every check, into reused buffers.
void time_decoding() {
  proto::ZstdCodec codec;
  proto::CodecScratch scratch;
  mesh::Buffer<uint8_t> encoding;
  mesh::ChunkMesh mesh;
  std::printf("C++ decode (zstd + every check), median per chunk:\n");
  for (size_t i = 0; i < names.size(); ++i) {
    const auto once = [&] {
      if (codec.decompress_into(frames[i], {}, size_t{4} << 20, encoding) ||
          proto::decode_mesh({encoding.data(), encoding.size()}, {}, scratch, mesh)) {
        std::fprintf(stderr, "%s: does not decode\n", names[i].c_str());
        std::exit(1);
      }
    };
    for (int w = 0; w < 20; ++w) once();
    std::vector<double> us;
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(300);
    while (us.size() < 30 || std::chrono::steady_clock::now() < end) {
      const auto t = std::chrono::steady_clock::now();
      once();
      us.push_back(
          std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t).count());
    }
    std::nth_element(us.begin(), us.begin() + us.size() / 2, us.end());
    std::printf("  %-24s %8.1f us\n", names[i].c_str(), us[us.size() / 2]);
  }
}

int main(int argc, char** argv) {
  const bool timing = argc == 3 && std::string(argv[2]) == "--time";
  if (argc != 2 && !timing) {
    std::fprintf(stderr, "usage: %s OUT_DIR [--time]\n", argv[0]);
    return 2;
  }
  out_dir = argv[1];

  // Format 1: terrain of seed 3 around the origin.
  const world::TerrainGenerator gen(3);
  world::ChunkMap map;
  for (int z = -2; z <= 2; ++z)
    for (int y = -3; y <= 6; ++y)
      for (int x = -2; x <= 2; ++x) map.insert({x, y, z}, gen.generate({x, y, z}));
  mesh::PaddedBlock block;
  int terrain = 0;
  bool dropped_found = false;
  for (int z = -1; z <= 1; ++z)
    for (int y = -2; y <= 1; ++y)
      for (int x = -1; x <= 1; ++x) {
        mesh::gather_padded_block(map, {x, y, z}, block);
        Meshed e = mesh_block(block);
        if (e.mesh.empty()) continue;
        const bool dropped = u32_at(e.encoding, 12) > 0;
        if (terrain < 3 || (dropped && !dropped_found)) {
          const std::string name =
              "terrain_" + std::to_string(x) + "_" + std::to_string(y) + "_" + std::to_string(z);
          write_fixture(name, e.encoding, e.mesh, 0, "seed 3 terrain chunk");
          ++terrain;
          dropped_found |= dropped;
        }
      }
  {
    mesh::gather_padded_block(map, {0, 5, 0}, block);
    Meshed e = mesh_block(block);
    if (!e.mesh.empty() || e.mesh.vertex_count() != 0) {
      std::fprintf(stderr, "sky chunk (0, 5, 0) is not empty\n");
      return 1;
    }
    write_fixture("empty_sky", e.encoding, e.mesh, 0, "seed 3 chunk (0, 5, 0): all air");
  }
  {
    Meshed e = mesh_function(
        {32, 32, 32}, [](int, int, int) { return world::Density{20000}; }, 3);
    write_fixture("full_rock", e.encoding, e.mesh, 0, "every sample solid: no vertex");
  }
  {
    Meshed e = mesh_function(
        {5, 7, 3},
        [](int x, int y, int z) {
          const float d =
              3.1f -
              std::sqrt(float((x - 2) * (x - 2) + (y - 3) * (y - 3) + (z - 1) * (z - 1)) + 0.3f);
          return world::quantize_density(d / 4.0f);
        },
        7);
    write_fixture("odd_cells_5_7_3", e.encoding, e.mesh, 0, "a ball in a 5x7x3-cell block");
  }
  {
    Meshed e = mesh_function(
        {1, 1, 1},
        [](int x, int y, int z) {
          return (x == 0 && y == 0 && z == 0) ? world::quantize_density(0.5f)
                                              : world::quantize_density(-0.5f);
        },
        3);
    write_fixture("worked_example", e.encoding, e.mesh, 0, "PROTOCOL 2.6");
  }
  {
    // Densities of very different sizes: many fractions round to 0 or 1024, so some table
    // triangles have zero area and are dropped.
    std::mt19937 rng(5);
    for (int attempt = 0; attempt < 50; ++attempt) {
      std::vector<world::Density> d(mesh::kBlockVolume);
      for (auto& v : d) {
        const int r = static_cast<int>(rng() % 4);
        v = r == 0 ? 1 : r == 1 ? -1 : r == 2 ? 32767 : -32767;
      }
      Meshed e = mesh_function(
          {8, 8, 8}, [&](int x, int y, int z) { return d[mesh::PaddedBlock::index(x, y, z)]; }, 4);
      if (u32_at(e.encoding, 12) == 0) continue;
      write_fixture("dropped_random", e.encoding, e.mesh, 0,
                    "random extreme densities in 8x8x8 cells: dropped triangles");
      break;
    }
  }

  // Format 2: level-of-detail chunks of a 4-level layout (as tests/lod_codec_test.cpp).
  {
    const world::TerrainSampler sampler(gen);
    world::LodLayout layout({.levels = 4, .top_radius = 1, .split_distance = 1.0});
    layout.update({40.5, gen.height_at(40, -20) + 2.0, -20.5});
    mesh::LodBlock lod_block;
    mesh::LodScratch lod;
    proto::CodecScratch scratch;
    int with_seams = 0, without = 0;
    std::vector<uint32_t> seen_seams;
    for (const world::LodChunk& c : layout.chunks()) {
      if (c.level == 0) continue;
      const world::LodSeams seams = layout.seams(c);
      const uint32_t key = seams.faces | uint32_t{seams.edges} << 8;
      const bool want = seams.empty()
                            ? without < 1
                            : with_seams < 5 && std::find(seen_seams.begin(), seen_seams.end(),
                                                          key) == seen_seams.end();
      if (!want) continue;
      mesh::ChunkMesh m;
      Bytes encoding;
      mesh::gather_lod_block(sampler, c, seams, lod_block);
      mesh::mesh_lod_chunk(lod_block, lod, m);
      if (m.empty()) continue;
      proto::encode_lod_mesh(m, lod, scratch, encoding);
      char name[96];
      std::snprintf(name, sizeof name, "lod%d_%d_%d_%d_f%02x_e%03x", c.level, c.c.x, c.c.y, c.c.z,
                    seams.faces, seams.edges);
      write_fixture(name, encoding, m, c.level, seams.empty() ? "no seams" : "with seams");
      if (seams.empty())
        ++without;
      else {
        ++with_seams;
        seen_seams.push_back(key);
      }
    }
    if (with_seams == 0 || without == 0) {
      std::fprintf(stderr, "layout gave %d seamed and %d seamless chunks\n", with_seams, without);
      return 1;
    }
  }

  // zstd frames of the server's codec: a full message, and a delta of one terrain chunk's
  // encoding against another's (the prefix mechanism is the same as for a chunk's own
  // versions).
  {
    mesh::gather_padded_block(map, {0, -2, -1}, block);
    const Meshed base = mesh_block(block);
    mesh::gather_padded_block(map, {1, -2, -1}, block);
    const Meshed next = mesh_block(block);
    proto::ZstdCodec codec;
    Bytes full, delta;
    codec.compress(next.encoding, {}, full);
    codec.compress(next.encoding, base.encoding, delta);
    write_file("delta.json", "{\n\"base\": \"" + hex(base.encoding) + "\",\n\"encoding\": \"" +
                                 hex(next.encoding) + "\",\n\"full_frame\": \"" + hex(full) +
                                 "\",\n\"delta_frame\": \"" + hex(delta) + "\"\n}\n");
    std::printf("delta: full frame %zu bytes, delta %zu bytes (encoding %zu)\n", full.size(),
                delta.size(), next.encoding.size());
  }

  // Every octahedral normal (PROTOCOL §2.4) as the C++ codec decodes it: normals.bin holds
  // 65,536 float32 triples (little-endian), entry u * 256 + v.
  {
    std::string table;
    table.reserve(65536 * 12);
    for (int u = 0; u < 256; ++u)
      for (int v = 0; v < 256; ++v) {
        const mesh::Vec3f n =
            proto::decode_normal(static_cast<uint8_t>(u), static_cast<uint8_t>(v));
        for (float c : {n.x, n.y, n.z}) {
          const uint32_t b = bits(c);
          for (int k = 0; k < 4; ++k) table += static_cast<char>(b >> (8 * k));
        }
      }
    write_file("normals.bin", table);
  }

  std::string manifest = "{\"fixtures\": [";
  for (size_t i = 0; i < names.size(); ++i) {
    if (i) manifest += ", ";
    manifest += "\"" + names[i] + "\"";
  }
  manifest += "]}\n";
  write_file("manifest.json", manifest);
  if (timing) time_decoding();
  return 0;
}
