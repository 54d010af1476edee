// voxel-cli mesh: a volume file (NIfTI, NRRD, raw float32, text) to a mesh file.
#include <chrono>
#include <cmath>
#include <optional>
#include <ostream>
#include <stdexcept>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/mesh_file.hpp"
#include "client-cli/volume_file.hpp"
#include "server/mesh/volume_mesher.hpp"

namespace vox::cli {
namespace {

using Clock = std::chrono::steady_clock;

constexpr const char* kMeshUsage =
    "usage: voxel-cli mesh INPUT --out OUTPUT [--dims X,Y,Z] [--iso V | --iso-percentile P] "
    "[--invert] [--spacing X,Y,Z | --no-spacing] [--threads N]";

po::options_description mesh_options() {
  po::options_description opts("voxel-cli mesh options");
  opts.add_options()("help,h", "show this help")(
      "input", po::value<std::string>()->required(),
      "volume file: .nii/.nii.gz (NIfTI-1), .nrrd/.nhdr (NRRD), raw float32 with --dims, "
      "else the seed's text format")("out,o", po::value<std::string>()->required(),
                                     "output mesh: .obj, .ply, .glb or .txt (seed 002 format)")(
      "dims", po::value<std::string>(), "X,Y,Z: INPUT is raw float32 little-endian, x fastest")(
      "iso", po::value<float>()->default_value(0.0f), "surface level")(
      "iso-percentile", po::value<double>(),
      "P in [0,100]: the surface level is the P-th percentile of the samples (instead of --iso)")(
      "invert", po::bool_switch(), "solid where the value is below --iso (Bourke's convention)")(
      "spacing", po::value<std::string>(),
      "X,Y,Z: voxel size; positions are scaled by it (default: the file's, NIfTI and NRRD)")(
      "no-spacing", po::bool_switch(), "keep positions in sample units, whatever the file says")(
      "threads", po::value<int>()->default_value(0), "worker threads, 0 = all cores");
  return opts;
}

// What the options ask for; an empty message when they are consistent, else why not.
struct MeshRequest {
  std::string input, output;
  mesh::VolumeMeshOptions options;
  std::optional<double> percentile;
  std::string problem;
};

MeshRequest mesh_request(const po::variables_map& vm) {
  MeshRequest r;
  r.input = vm["input"].as<std::string>();
  r.output = vm["out"].as<std::string>();
  r.options.iso = vm["iso"].as<float>();
  r.options.invert = vm["invert"].as<bool>();
  r.options.threads = vm["threads"].as<int>();
  if (vm.count("iso-percentile")) r.percentile = vm["iso-percentile"].as<double>();
  if (!std::isfinite(r.options.iso)) {
    r.problem = "--iso must be a finite number";
  } else if (r.options.threads < 0 || r.options.threads > 1024) {
    r.problem = "--threads must be between 0 and 1024";
  } else if (r.percentile &&
             (!(*r.percentile >= 0.0 && *r.percentile <= 100.0) || !vm["iso"].defaulted())) {
    r.problem = "--iso-percentile takes a number in [0,100] and replaces --iso";
  } else if (vm.count("spacing") && vm["no-spacing"].as<bool>()) {
    r.problem = "--spacing and --no-spacing contradict each other";
  }
  return r;
}

// The spacing the mesh is scaled by: --spacing, else none with --no-spacing, else the
// file's own (NIfTI, NRRD), which must then be usable.
std::optional<std::array<float, 3>> spacing_for(const po::variables_map& vm,
                                                const LoadedVolume& loaded,
                                                const std::string& input) {
  if (vm.count("spacing")) {
    const std::array<float, 3> s = parse_vec3(vm["spacing"].as<std::string>(), "--spacing");
    for (float v : s)
      if (!(v > 0.0f)) throw std::invalid_argument("--spacing values must be positive");
    return s;
  }
  if (vm["no-spacing"].as<bool>() || !loaded.spacing) return std::nullopt;
  for (float v : *loaded.spacing) {
    if (v == 0.0f) {
      throw VolumeError(input +
                        ": the file's voxel spacing is not usable (zero, negative or not a "
                        "number); give --spacing X,Y,Z or --no-spacing");
    }
  }
  if (*loaded.spacing == std::array<float, 3>{1, 1, 1}) return std::nullopt;
  return loaded.spacing;
}

// Reads, meshes and writes; prints one line. Throws what the readers and writers throw.
int run_mesh(const po::variables_map& vm, MeshRequest& r, std::ostream& out) {
  mesh_format_for(r.output);  // refuse a bad extension before doing any work
  // Raw samples are mapped, not copied; other formats are decoded to floats.
  std::optional<RawVolumeFile> raw;
  LoadedVolume loaded;
  if (vm.count("dims")) {
    raw.emplace(r.input, parse_dims(vm["dims"].as<std::string>()));
  } else {
    loaded = load_volume(r.input, std::nullopt);
  }
  const std::array<int, 3> dims = raw ? raw->dims() : loaded.volume.dims;
  const std::span<const float> values =
      raw ? raw->values() : std::span<const float>(loaded.volume.values);
  const std::optional<std::array<float, 3>> spacing = spacing_for(vm, loaded, r.input);
  const auto t0 = Clock::now();
  mesh::FloatVolumeView view{dims, values, {}};
  if (raw) view.release = [&raw](size_t begin, size_t end) { raw->release(begin, end); };
  mesh::ChunkMesh result;
  try {
    if (r.percentile) r.options.iso = mesh::value_percentile(values, *r.percentile);
    result = mesh::mesh_float_volume(view, r.options);
  } catch (const std::domain_error& e) {
    throw VolumeError(r.input + ": " + e.what());
  }
  raw.reset();  // the samples are not needed any more: give their memory back
  loaded = {};
  if (spacing) mesh::apply_spacing(result, *spacing);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  write_mesh(r.output, result);
  out << "meshed " << dims[0] << "x" << dims[1] << "x" << dims[2] << " samples";
  if (r.percentile) out << " at iso " << r.options.iso;
  out << ": " << result.vertex_count() << " vertices, " << result.triangle_count()
      << " triangles in " << ms << " ms -> " << r.output;
  if (result.empty()) out << " (no surface: every sample is on one side of the level)";
  out << "\n";
  return 0;
}

}  // namespace

int mesh_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const po::options_description opts = mesh_options();
  po::positional_options_description positional;
  positional.add("input", 1);
  po::variables_map vm;
  const int rc = parse_options(args, opts, &positional, kMeshUsage, vm, out, err);
  if (rc >= 0) return rc;
  MeshRequest request = mesh_request(vm);
  if (!request.problem.empty()) {
    err << "voxel-cli: error: " << request.problem << "\n";
    return 2;
  }
  return guarded(err, [&] { return run_mesh(vm, request, out); });
}

}  // namespace vox::cli
