// voxel-cli export: fetch the meshes around a point, decode them and write one welded
// mesh (.obj, .ply or .glb).
#include <algorithm>
#include <chrono>
#include <iomanip>
#include <ostream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/mesh_file.hpp"
#include "client-cli/region_fetch.hpp"
#include "client/voxel_client.hpp"
#include "server/mesh/lod_welder.hpp"
#include "server/mesh/mesh_welder.hpp"

namespace vox::cli {

using namespace std::chrono_literals;

namespace {

// The chunks of every level the client holds (a level-of-detail view) welded into one mesh
// in world positions (lod_welder.hpp).
mesh::ChunkMesh weld_levels(const client::Client& c, uint32_t levels) {
  std::vector<mesh::ChunkMesh> decoded;
  std::vector<mesh::LodPart> parts;
  for (uint32_t level = 0; level <= levels; ++level) {
    for (const auto& [key, held] : level == 0 ? c.chunks() : c.lod_chunks(level)) {
      auto mesh = proto::decode_mesh(held.encoding);
      if (!mesh) throw std::runtime_error("bad mesh from the server: " + mesh.error());
      decoded.push_back(std::move(*mesh));
      parts.push_back({level, {std::get<0>(key), std::get<1>(key), std::get<2>(key)}, nullptr});
    }
  }
  for (size_t i = 0; i < parts.size(); ++i) parts[i].mesh = &decoded[i];
  return mesh::weld_lod_parts(std::move(parts));
}

}  // namespace

int export_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("export");
  add_view_options(opts, "X,Y,Z: centre", true);
  opts.add_options()("out,o", po::value<std::string>()->required(), "output: .obj, .ply or .glb")(
      "lod-distance", po::value<float>(),
      "a level-of-detail view to the horizon: coarser chunks split within this many of their "
      "sides (1 .. the server's max_lod_distance); level 0 reaches --radius chunks")(
      "lod-level", po::value<uint32_t>()->default_value(6),
      "with --lod-distance: the coarsest level (6: 2,048 voxels and more)");
  po::variables_map vm;
  const int rc =
      parse_options(args, opts, nullptr, "usage: voxel-cli export --at X,Y,Z --radius N --out FILE",
                    vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const std::string output = vm["out"].as<std::string>();
    mesh_format_for(output);
    const auto at = parse_vec3(vm["at"].as<std::string>(), "--at");
    const bool lod = vm.count("lod-distance") > 0;
    const uint32_t levels = lod ? vm["lod-level"].as<uint32_t>() : 0;
    const auto region = fetch_region(
        server_access(vm), "voxel-cli-export", at, vm["radius"].as<uint32_t>(),
        timeout_of(vm["timeout"].as<double>()), levels, lod ? vm["lod-distance"].as<float>() : 0);
    const client::Client& c = *region;
    if (lod) {
      const mesh::ChunkMesh all = weld_levels(c, levels);
      write_mesh(output, all);
      size_t chunks = c.chunks().size();
      for (uint32_t level = 1; level <= levels; ++level) chunks += c.lod_chunks(level).size();
      out << "exported " << chunks << " chunks of levels 0-" << levels << ": " << all.vertex_count()
          << " vertices, " << all.triangle_count() << " triangles -> " << output << "\n";
      return 0;
    }
    // Decode every chunk into a dense grid over their bounding box, then weld.
    std::array<int, 3> lo{INT32_MAX, INT32_MAX, INT32_MAX}, hi{INT32_MIN, INT32_MIN, INT32_MIN};
    for (const auto& [key, held] : c.chunks()) {
      const int k[3] = {std::get<0>(key), std::get<1>(key), std::get<2>(key)};
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], k[a]);
        hi[a] = std::max(hi[a], k[a]);
      }
    }
    const std::array<int, 3> grid{hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    std::vector<mesh::ChunkMesh> parts(static_cast<size_t>(grid[0]) * grid[1] * grid[2]);
    for (const auto& [key, held] : c.chunks()) {
      const size_t i = static_cast<size_t>(std::get<0>(key) - lo[0]) +
                       static_cast<size_t>(grid[0]) *
                           (static_cast<size_t>(std::get<1>(key) - lo[1]) +
                            static_cast<size_t>(grid[1]) * (std::get<2>(key) - lo[2]));
      auto decoded = proto::decode_mesh(held.encoding);
      if (!decoded) throw std::runtime_error("bad mesh from the server: " + decoded.error());
      parts[i] = std::move(*decoded);
    }
    const float k = 32.0f;
    const mesh::ChunkMesh welded = mesh::weld_chunk_grid(
        parts, grid,
        mesh::Vec3f{k * static_cast<float>(lo[0]), k * static_cast<float>(lo[1]),
                    k * static_cast<float>(lo[2])});
    write_mesh(output, welded);
    out << "exported " << c.chunks().size() << " chunks: " << welded.vertex_count() << " vertices, "
        << welded.triangle_count() << " triangles -> " << output << "\n";
    return 0;
  });
}

}  // namespace vox::cli
