// voxel-cli ray | ground | sample: a query about the world's samples over the protocol
// (docs/PROTOCOL.md 4.13), for any role.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <ostream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/server_request.hpp"

namespace vox::cli {
namespace {

wire::QueryResult run_query(const po::variables_map& vm, wire::Envelope m) {
  m.mutable_query()->set_request_id(1);
  return server_request(
             vm, m,
             [](const wire::Envelope& e) {
               return e.has_query_result() && e.query_result().request_id() == 1;
             },
             "QueryResult")
      .query_result();
}

std::string fixed(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

std::string vec(const wire::Vec3& v) {
  return fixed(v.x()) + "," + fixed(v.y()) + "," + fixed(v.z());
}

int print_hit(const wire::QueryResult& r, std::ostream& out, std::ostream& err) {
  if (r.status() != wire::QueryResult::OK) {
    err << "voxel-cli: refused: " << wire::QueryResult::Status_Name(r.status()) << ": "
        << r.reason() << "\n";
    return 1;
  }
  if (!r.hit()) {
    out << "no hit\n";
    return 0;
  }
  out << "hit " << vec(r.point()) << " normal " << vec(r.normal()) << " material " << r.material()
      << " distance " << fixed(r.distance()) << "\n";
  return 0;
}

wire::Vec3 to_wire(const std::array<float, 3>& v) {
  wire::Vec3 w;
  w.set_x(v[0]), w.set_y(v[1]), w.set_z(v[2]);
  return w;
}

}  // namespace

int query_command(const std::string& kind, const std::vector<std::string>& args, std::ostream& out,
                  std::ostream& err) {
  po::options_description opts = network_options(kind);
  const char* synopsis = nullptr;
  if (kind == "ray") {
    synopsis = "usage: voxel-cli ray --from X,Y,Z --dir X,Y,Z [--max D]";
    opts.add_options()("from", po::value<std::string>()->required(), "X,Y,Z: the ray's origin")(
        "dir", po::value<std::string>()->required(), "X,Y,Z: its direction (any length)")(
        "max", po::value<float>()->default_value(256), "how far to look, in voxels");
  } else if (kind == "ground") {
    synopsis = "usage: voxel-cli ground --at X,Z [--from-y H] [--depth D]";
    opts.add_options()("at", po::value<std::string>()->required(), "X,Z: the column")(
        "from-y", po::value<float>()->default_value(256), "search down from this height")(
        "depth", po::value<float>()->default_value(512), "how far down to look, in voxels");
  } else {
    synopsis = "usage: voxel-cli sample --min X,Y,Z --max X,Y,Z [--list] [--out FILE]";
    opts.add_options()("min", po::value<std::string>()->required(),
                       "X,Y,Z: the box's lowest sample")(
        "max", po::value<std::string>()->required(), "X,Y,Z: its highest sample (inclusive)")(
        "list", "print every sample: x,y,z density material")(
        "out", po::value<std::string>(),
        "write the densities (int16, little-endian) and materials (bytes) to FILE.density and "
        "FILE.material");
  }
  po::variables_map vm;
  const int rc = parse_options(args, opts, nullptr, synopsis, vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&]() -> int {
    wire::Envelope m;
    auto* q = m.mutable_query();
    if (kind == "ray") {
      auto* r = q->mutable_raycast();
      *r->mutable_origin() = to_wire(parse_vec3(vm["from"].as<std::string>(), "--from"));
      *r->mutable_direction() = to_wire(parse_vec3(vm["dir"].as<std::string>(), "--dir"));
      r->set_max_distance(vm["max"].as<float>());
      return print_hit(run_query(vm, m), out, err);
    }
    if (kind == "ground") {
      const auto at = parse_vec2(vm["at"].as<std::string>(), "--at");
      auto* g = q->mutable_ground();
      g->set_x(at[0]), g->set_z(at[1]);
      g->set_from_y(vm["from-y"].as<float>());
      g->set_max_depth(vm["depth"].as<float>());
      const wire::QueryResult r = run_query(vm, m);
      if (r.status() == wire::QueryResult::OK && r.hit())
        out << "ground at y = " << fixed(r.point().y()) << " (material " << r.material()
            << ", normal " << vec(r.normal()) << ")\n";
      else if (r.status() == wire::QueryResult::OK)
        out << "no ground within " << vm["depth"].as<float>()
            << " voxels below y = " << vm["from-y"].as<float>() << "\n";
      return r.status() == wire::QueryResult::OK ? 0 : print_hit(r, out, err);
    }
    const auto lo = parse_corner(vm["min"].as<std::string>(), "--min");
    const auto hi = parse_corner(vm["max"].as<std::string>(), "--max");
    auto* b = q->mutable_samples()->mutable_box();
    b->set_min_x(lo[0]), b->set_min_y(lo[1]), b->set_min_z(lo[2]);
    b->set_max_x(hi[0]), b->set_max_y(hi[1]), b->set_max_z(hi[2]);
    const wire::QueryResult r = run_query(vm, m);
    if (r.status() != wire::QueryResult::OK) return print_hit(r, out, err);
    const std::string& d = r.densities();
    const std::string& mat = r.materials();
    if (d.size() != 2 * mat.size()) throw std::runtime_error("the answer's planes differ in size");
    size_t solid = 0, i = 0;
    std::map<int, size_t> by_material;
    for (int32_t z = lo[2]; z <= hi[2]; ++z)
      for (int32_t y = lo[1]; y <= hi[1]; ++y)
        for (int32_t x = lo[0]; x <= hi[0] && i < mat.size(); ++x, ++i) {
          const auto density = static_cast<int16_t>(static_cast<uint8_t>(d[2 * i]) |
                                                    static_cast<uint8_t>(d[2 * i + 1]) << 8);
          const int material = static_cast<uint8_t>(mat[i]);
          if (density > 0) ++solid, ++by_material[material];
          if (vm.count("list"))
            out << x << "," << y << "," << z << " " << density << " " << material << "\n";
        }
    out << mat.size() << " samples, " << solid << " solid";
    for (const auto& [material, n] : by_material) out << "; material " << material << ": " << n;
    out << "\n";
    if (vm.count("out")) {
      const std::string base = vm["out"].as<std::string>();
      std::ofstream(base + ".density", std::ios::binary) << d;
      std::ofstream(base + ".material", std::ios::binary) << mat;
      out << "wrote " << base << ".density and " << base << ".material\n";
    }
    return 0;
  });
}

}  // namespace vox::cli
