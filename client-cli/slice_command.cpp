// voxel-cli slice: a top-down contour map. The meshes around a point are fetched and
// rasterised into a height map (the highest surface above each 1-voxel grid point), then
// marching squares (seed 004) traces the terrain's horizontal slices at several heights;
// each level is drawn as one SVG path coloured by height.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <ostream>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "client-cli/region_fetch.hpp"
#include "client/voxel_client.hpp"

namespace vox::cli {
namespace {

using namespace std::chrono_literals;

struct HeightMap {
  int x0 = 0, z0 = 0, size = 0;  // samples (x0 + i, z0 + j), i, j in [0, size)
  std::vector<float> height;     // -inf where no surface
  float& at(int i, int j) { return height[static_cast<size_t>(i) + static_cast<size_t>(size) * j]; }
  float at(int i, int j) const {
    return height[static_cast<size_t>(i) + static_cast<size_t>(size) * j];
  }
};

// The highest surface point over each grid point, from every triangle's top-down footprint.
void rasterise(const mesh::ChunkMesh& m, float ox, float oy, float oz, HeightMap& map) {
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const mesh::Vec3f a = m.positions[m.indices[t]], b = m.positions[m.indices[t + 1]],
                      c = m.positions[m.indices[t + 2]];
    const float ax = a.x + ox, az = a.z + oz, bx = b.x + ox, bz = b.z + oz, cx = c.x + ox,
                cz = c.z + oz;
    const float det = (bz - cz) * (ax - cx) + (cx - bx) * (az - cz);
    if (std::fabs(det) < 1e-12f) continue;  // seen edge-on from above
    const int i0 = std::max(0, static_cast<int>(std::ceil(std::min({ax, bx, cx}))) - map.x0);
    const int i1 =
        std::min(map.size - 1, static_cast<int>(std::floor(std::max({ax, bx, cx}))) - map.x0);
    const int j0 = std::max(0, static_cast<int>(std::ceil(std::min({az, bz, cz}))) - map.z0);
    const int j1 =
        std::min(map.size - 1, static_cast<int>(std::floor(std::max({az, bz, cz}))) - map.z0);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const float px = static_cast<float>(map.x0 + i), pz = static_cast<float>(map.z0 + j);
        const float l1 = ((bz - cz) * (px - cx) + (cx - bx) * (pz - cz)) / det;
        const float l2 = ((cz - az) * (px - cx) + (ax - cx) * (pz - cz)) / det;
        const float l3 = 1.0f - l1 - l2;
        if (l1 < -1e-6f || l2 < -1e-6f || l3 < -1e-6f) continue;
        const float y = l1 * (a.y + oy) + l2 * (b.y + oy) + l3 * (c.y + oy);
        map.at(i, j) = std::max(map.at(i, j), y);
      }
  }
}

// Marching squares on (height - level): appends "M x y L x y" per contour segment.
// Crossings are computed per grid edge from its lower-index end, so the two cells that
// share an edge produce the same point and contours join exactly.
void contour(const HeightMap& map, float level, float floor_value, std::string& path) {
  auto value = [&](int i, int j) {
    const float h = map.at(i, j);
    return (std::isfinite(h) ? h : floor_value) - level;
  };
  auto crossing = [&](int i0, int j0, int i1, int j1) {  // (i1, j1) is (i0 + 1, j0) or (i0, j0 + 1)
    const float v0 = value(i0, j0), v1 = value(i1, j1);
    const float t = v0 / (v0 - v1);
    return std::pair<float, float>{static_cast<float>(i0) + t * static_cast<float>(i1 - i0),
                                   static_cast<float>(j0) + t * static_cast<float>(j1 - j0)};
  };
  char buf[96];
  for (int j = 0; j + 1 < map.size; ++j)
    for (int i = 0; i + 1 < map.size; ++i) {
      // Corners: 0 (i,j) 1 (i+1,j) 2 (i+1,j+1) 3 (i,j+1); bit set when above the level.
      const bool c0 = value(i, j) > 0, c1 = value(i + 1, j) > 0, c2 = value(i + 1, j + 1) > 0,
                 c3 = value(i, j + 1) > 0;
      const int cell = c0 | c1 << 1 | c2 << 2 | c3 << 3;
      if (cell == 0 || cell == 15) continue;
      // Edges: 0 bottom (0-1), 1 right (1-2), 2 top (3-2), 3 left (0-3).
      const std::pair<float, float> e[4] = {
          crossing(i, j, i + 1, j), crossing(i + 1, j, i + 1, j + 1),
          crossing(i, j + 1, i + 1, j + 1), crossing(i, j, i, j + 1)};
      int segments[2][2];
      int n = 0;
      const bool centre_above =
          (value(i, j) + value(i + 1, j) + value(i + 1, j + 1) + value(i, j + 1)) > 0;
      switch (cell) {
        case 1:
        case 14:
          segments[n][0] = 3, segments[n++][1] = 0;
          break;
        case 2:
        case 13:
          segments[n][0] = 0, segments[n++][1] = 1;
          break;
        case 3:
        case 12:
          segments[n][0] = 3, segments[n++][1] = 1;
          break;
        case 4:
        case 11:
          segments[n][0] = 1, segments[n++][1] = 2;
          break;
        case 6:
        case 9:
          segments[n][0] = 0, segments[n++][1] = 2;
          break;
        case 7:
        case 8:
          segments[n][0] = 3, segments[n++][1] = 2;
          break;
        case 5:  // saddle: corners 0 and 2 above
          if (centre_above) {
            segments[n][0] = 3, segments[n++][1] = 2;
            segments[n][0] = 0, segments[n++][1] = 1;
          } else {
            segments[n][0] = 3, segments[n++][1] = 0;
            segments[n][0] = 1, segments[n++][1] = 2;
          }
          break;
        case 10:  // saddle: corners 1 and 3 above
          if (centre_above) {
            segments[n][0] = 3, segments[n++][1] = 0;
            segments[n][0] = 1, segments[n++][1] = 2;
          } else {
            segments[n][0] = 0, segments[n++][1] = 1;
            segments[n][0] = 3, segments[n++][1] = 2;
          }
          break;
      }
      for (int s = 0; s < n; ++s) {
        const auto& p = e[segments[s][0]];
        const auto& q = e[segments[s][1]];
        std::snprintf(buf, sizeof buf, "M%.3f %.3f L%.3f %.3f ", p.first, p.second, q.first,
                      q.second);
        path += buf;
      }
    }
}

}  // namespace

int slice_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts = network_options("slice");
  add_view_options(opts, "X,Z: map centre", true);
  opts.add_options()("y", po::value<float>()->required(),
                     "height of the view centre (world voxels)")(
      "levels", po::value<int>()->default_value(8), "number of contour heights (1..64)")(
      "out,o", po::value<std::string>()->required(), "output .svg");
  po::variables_map vm;
  const int rc =
      parse_options(args, opts, nullptr,
                    "usage: voxel-cli slice --y H --at X,Z --radius N --out map.svg", vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const auto xz = parse_vec2(vm["at"].as<std::string>(), "--at");
    const float y = vm["y"].as<float>();
    const int levels = vm["levels"].as<int>();
    if (!std::isfinite(y)) throw std::invalid_argument("--y must be finite");
    if (levels < 1 || levels > 64) throw std::invalid_argument("--levels must be 1..64");
    const std::string output = vm["out"].as<std::string>();
    const auto radius = vm["radius"].as<uint32_t>();
    const auto region = fetch_region(server_access(vm), "voxel-cli-slice", {xz[0], y, xz[1]},
                                     radius, timeout_of(vm["timeout"].as<double>()));
    const client::Client& c = *region;
    HeightMap map;
    map.size = static_cast<int>(2 * radius + 1) * 32 + 1;
    map.x0 = static_cast<int>(std::floor(xz[0])) - map.size / 2;
    map.z0 = static_cast<int>(std::floor(xz[1])) - map.size / 2;
    map.height.assign(static_cast<size_t>(map.size) * map.size, -INFINITY);
    for (const auto& [key, held] : c.chunks()) {
      auto m = proto::decode_mesh(held.encoding);
      if (!m) throw std::runtime_error("bad mesh from the server: " + m.error());
      rasterise(*m, 32.0f * static_cast<float>(std::get<0>(key)),
                32.0f * static_cast<float>(std::get<1>(key)),
                32.0f * static_cast<float>(std::get<2>(key)), map);
    }
    float lo = INFINITY, hi = -INFINITY;
    for (float h : map.height)
      if (std::isfinite(h)) lo = std::min(lo, h), hi = std::max(hi, h);
    if (!std::isfinite(lo)) throw std::runtime_error("no terrain seen from above in that area");
    const std::string tmp = output + ".tmp";
    {
      std::ofstream svg(tmp);
      svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 " << map.size - 1 << " "
          << map.size - 1 << "\" width=\"" << 4 * (map.size - 1) << "\" height=\""
          << 4 * (map.size - 1) << "\">\n"
          << "<!-- voxeld contour map: x " << map.x0 << ".." << map.x0 + map.size - 1 << ", z "
          << map.z0 << ".." << map.z0 + map.size - 1 << ", heights " << lo << ".." << hi << " -->\n"
          << "<rect width=\"100%\" height=\"100%\" fill=\"#101418\"/>\n";
      for (int k = 0; k < levels; ++k) {
        const float level =
            lo + (hi - lo) * (static_cast<float>(k) + 0.5f) / static_cast<float>(levels);
        std::string path;
        contour(map, level, lo - 1.0f, path);
        const float t = (static_cast<float>(k) + 0.5f) /
                        static_cast<float>(levels);  // blue (low) to red (high)
        char colour[16];
        std::snprintf(colour, sizeof colour, "#%02x%02x%02x", static_cast<int>(40 + 215 * t),
                      static_cast<int>(120 + 80 * (1 - std::fabs(2 * t - 1))),
                      static_cast<int>(255 - 215 * t));
        svg << "<path data-height=\"" << level << "\" stroke=\"" << colour
            << "\" stroke-width=\"0.4\" fill=\"none\" d=\"" << path << "\"/>\n";
      }
      svg << "</svg>\n";
      if (!svg) throw std::runtime_error("cannot write " + output);
    }
    std::rename(tmp.c_str(), output.c_str());
    out << "sliced " << c.chunks().size() << " chunks at " << levels << " heights from " << lo
        << " to " << hi << " -> " << output << "\n";
    return 0;
  });
}

}  // namespace vox::cli
