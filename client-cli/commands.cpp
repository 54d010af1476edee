#include "client-cli/commands.hpp"

#include <boost/program_options.hpp>
#include <chrono>
#include <cmath>
#include <ostream>

#include "client-cli/cli_options.hpp"
#include "client-cli/mesh_file.hpp"
#include "server/mesh/region_mesher.hpp"
#include "server/world/parallel.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::cli {
namespace {

constexpr const char* kUsage =
    "usage: voxel-cli COMMAND [options]\n"
    "commands:\n"
    "  info                    the server's version, seed, limits and player count\n"
    "  brush | explode | smooth | paint | stamp   one edit; prints the result\n"
    "  ray --from X,Y,Z --dir X,Y,Z   where a ray first meets the terrain\n"
    "  ground --at X,Z         the terrain's height at a column (aim edits at the surface)\n"
    "  sample --min X,Y,Z --max X,Y,Z   the densities and materials of a box\n"
    "  script FILE             run a file of edits (one per line, same options)\n"
    "  watch --at X,Y,Z        print every chunk update around a point\n"
    "  export --at X,Y,Z --out FILE   fetch meshes around a point: .obj, .ply or .glb\n"
    "  slice --y H --at X,Z --out map.svg   a top-down contour map of the terrain\n"
    "  mesh INPUT --out FILE   mesh a volume offline (NIfTI, NRRD, raw float32 or text)\n"
    "  demo --out FILE         generate terrain around the origin and mesh it offline\n"
    "  world info|log|history|verify WORLD   a world directory (or postgresql:// URI), read-only\n"
    "  world migrate --from WORLD --to WORLD   a single node's world into a cluster's, or back\n"
    "  world backup WORLD --out FILE   a consistent copy while voxeld runs (SQLite worlds)\n"
    "  world restore FILE --to DIR [--force]   a backup into place, then verified\n"
    "  keygen --out NAME       an Ed25519 key pair for player tokens (NAME.key, NAME.pub)\n"
    "  token --key NAME.key --player ID --name NAME [--role R] [--ttl S]   a player token\n"
    "  region add|list|remove  manage protected regions (with an admin token)\n"
    "  players | kick | ban | unban | bans   who is on; keep a player or address out (admin)\n"
    "Network commands take --server HOST:PORT (default 127.0.0.1:7777).\n"
    "Run 'voxel-cli COMMAND --help' for a command's options.\n";

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

int demo_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts("voxel-cli demo options");
  opts.add_options()("help,h", "show this help")(
      "out,o", po::value<std::string>()->default_value("demo.obj"),
      "output mesh: .obj, .ply or .txt")("seed", po::value<uint64_t>()->default_value(1),
                                         "world seed")("radius", po::value<int>()->default_value(4),
                                                       "half-width of the area in chunks (1..16)");
  po::variables_map vm;
  const int rc =
      parse_options(args, opts, nullptr,
                    "usage: voxel-cli demo [--out FILE] [--seed N] [--radius R]", vm, out, err);
  if (rc >= 0) return rc;
  const int radius = vm["radius"].as<int>();
  if (radius < 1 || radius > 16) {
    err << "voxel-cli: error: --radius must be between 1 and 16\n";
    return 2;
  }
  const std::string output = vm["out"].as<std::string>();
  return guarded(err, [&] {
    mesh_format_for(output);
    const world::TerrainGenerator generator(vm["seed"].as<uint64_t>());
    const mesh::ChunkBox box{{-radius, -3, -radius}, {radius - 1, 2, radius - 1}};
    const auto t0 = Clock::now();
    std::vector<world::Chunk> chunks(box.count());
    tbb::task_arena arena(arena_concurrency(0));
    parallel_for_index(arena, chunks.size(),
                       [&](size_t i) { chunks[i] = generator.generate(box.at(i)); });
    world::ChunkMap map;
    for (size_t i = 0; i < chunks.size(); ++i) map.insert(box.at(i), std::move(chunks[i]));
    const double gen_ms = ms_since(t0);
    const auto t1 = Clock::now();
    const mesh::ChunkMesh result = mesh::mesh_region(map, box);
    const double mesh_ms = ms_since(t1);
    write_mesh(output, result);
    out << "demo world seed " << generator.seed() << ": " << box.count() << " chunks generated in "
        << gen_ms << " ms, meshed in " << mesh_ms << " ms: " << result.vertex_count()
        << " vertices, " << result.triangle_count() << " triangles -> " << output << "\n";
    return 0;
  });
}

int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    (args.empty() ? err : out) << kUsage;
    return args.empty() ? 2 : 0;
  }
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (args[0] == "mesh") return mesh_command(rest, out, err);
  if (args[0] == "demo") return demo_command(rest, out, err);
  if (args[0] == "info") return info_command(rest, out, err);
  if (args[0] == "script") return script_command(rest, out, err);
  if (args[0] == "watch") return watch_command(rest, out, err);
  if (args[0] == "export") return export_command(rest, out, err);
  if (args[0] == "slice") return slice_command(rest, out, err);
  if (args[0] == "world") return world_command(rest, out, err);
  if (args[0] == "keygen") return keygen_command(rest, out, err);
  if (args[0] == "token") return token_command(rest, out, err);
  if (args[0] == "region") return region_command(rest, out, err);
  for (const char* action : {"players", "kick", "ban", "unban", "bans", "rollback"}) {
    if (args[0] == action) return admin_command(action, rest, out, err);
  }
  for (const char* kind : {"brush", "explode", "smooth", "paint", "stamp"}) {
    if (args[0] == kind) return edit_command(kind, rest, out, err);
  }
  for (const char* kind : {"ray", "ground", "sample"}) {
    if (args[0] == kind) return query_command(kind, rest, out, err);
  }
  err << "voxel-cli: unknown command '" << args[0] << "'\n" << kUsage;
  return 2;
}

}  // namespace vox::cli
