// voxel-cli's network commands against a real voxeld on loopback.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "client-cli/commands.hpp"
#include "client/voxel_client.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/server_process.hpp"
#include "tests/temp_dir.hpp"

namespace vox::cli {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class CliNetwork : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { server_ = new test::ServerProcess(); }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }
  std::string server() const { return "127.0.0.1:" + std::to_string(server_->port()); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  int run(std::vector<std::string> args, bool with_server = true) {
    if (with_server) {
      args.push_back("--server");
      args.push_back(server());
    }
    out_.str("");
    err_.str("");
    return run_cli(args, out_, err_);
  }
  std::string surface_at(int x, int z) const {
    const float y = world::TerrainGenerator(1).height_at(x, z);
    return std::to_string(x) + "," + std::to_string(y) + "," + std::to_string(z);
  }

  static test::ServerProcess* server_;
  test::TempDir dir_{"cli_net"};  // the test's files
  std::ostringstream out_, err_;
};
test::ServerProcess* CliNetwork::server_ = nullptr;

TEST_F(CliNetwork, InfoPrintsTheServersWelcome) {
  ASSERT_EQ(run({"info"}), 0) << err_.str();
  EXPECT_NE(out_.str().find("world seed:      1"), std::string::npos) << out_.str();
  EXPECT_NE(out_.str().find("players:"), std::string::npos);
}

TEST_F(CliNetwork, UnreachableServerIsAOneLineErrorAndExitOne) {
  EXPECT_EQ(run({"info", "--server", "127.0.0.1:1"}, false), 1);
  const std::string err = err_.str();
  EXPECT_NE(err.find("cannot connect"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1);
  EXPECT_EQ(run({"brush", "--at", "0,0,0", "--radius", "2", "--server", "nonsense"}, false), 2);
}

TEST_F(CliNetwork, EveryEditCommandIsAcceptedOrRefusedWithItsReason) {
  const std::string at = surface_at(40, 40);
  ASSERT_EQ(run({"brush", "--at", at, "--radius", "3", "--strength", "1", "--material", "4"}), 0)
      << err_.str();
  EXPECT_NE(out_.str().find("accepted"), std::string::npos);
  EXPECT_NE(out_.str().find(" ms"), std::string::npos);
  EXPECT_EQ(run({"explode", "--at", at, "--radius", "5", "--power", "2"}), 0) << err_.str();
  EXPECT_EQ(run({"smooth", "--at", at, "--radius", "4", "--strength", "0.5"}), 0) << err_.str();
  EXPECT_EQ(run({"paint", "--at", at, "--radius", "4", "--material", "7"}), 0) << err_.str();
  EXPECT_EQ(run({"stamp", "--shape", "sphere", "--at", at, "--radius", "3", "--material", "5"}), 0)
      << err_.str();
  EXPECT_EQ(run({"stamp", "--min", "30,0,30", "--max", "34,4,34", "--air"}), 0) << err_.str();
  EXPECT_EQ(run({"explode", "--at", at, "--radius", "99"}), 1);
  EXPECT_NE(err_.str().find("refused: BAD_RADIUS"), std::string::npos) << err_.str();
  EXPECT_EQ(run({"paint", "--at", at, "--radius", "2", "--material", "0"}), 1);
  EXPECT_NE(err_.str().find("BAD_MATERIAL"), std::string::npos) << err_.str();
  EXPECT_EQ(run({"brush", "--at", "nan,0,0", "--radius", "2"}), 2)
      << "NaN is caught before sending";
  EXPECT_EQ(run({"brush", "--radius", "2"}), 2) << "--at is required";
  EXPECT_EQ(run({"brush", "--help"}, false), 0);
}

TEST_F(CliNetwork, ScriptRunsEditsAndRefusesBadLinesBeforeSending) {
  std::ofstream(path("ok.txt"))
      << "# a scene\nbrush --at 1,0,1 --radius 3\n\nexplode --at 20,0,20 --radius 4 --power 2\n"
         "stamp --shape sphere --at 10,5,10 --radius 3 --material 5\n";
  ASSERT_EQ(run({"script", path("ok.txt")}), 0) << err_.str();
  EXPECT_NE(out_.str().find("3 edits (0 refused)"), std::string::npos) << out_.str();
  EXPECT_NE(out_.str().find("edits/s"), std::string::npos);
  std::ofstream(path("bad.txt")) << "brush --at 1,0,1 --radius 3\nteleport --at 1,2,3\n";
  EXPECT_EQ(run({"script", path("bad.txt")}), 2);
  EXPECT_NE(err_.str().find("line 2"), std::string::npos) << err_.str();
  std::ofstream(path("refused.txt")) << "explode --at 1,0,1 --radius 500\n";
  EXPECT_EQ(run({"script", path("refused.txt")}), 1);
  EXPECT_EQ(run({"script", path("missing.txt")}), 1);
}

TEST_F(CliNetwork, WatchPrintsUpdatesAndASummary) {
  ASSERT_EQ(run({"watch", "--at", surface_at(0, 0), "--radius", "1", "--for", "1.5"}), 0)
      << err_.str();
  EXPECT_NE(out_.str().find("full"), std::string::npos) << out_.str();
  EXPECT_NE(out_.str().find("watched"), std::string::npos);
}

// The OBJ file's positions and triangles (1-based indices made 0-based).
struct ObjMesh {
  std::vector<std::array<float, 3>> positions;
  std::vector<std::array<uint32_t, 3>> triangles;
};

ObjMesh read_obj(const std::string& text) {
  ObjMesh m;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    std::istringstream l(line);
    std::string tag;
    l >> tag;
    if (tag == "v") {
      std::array<float, 3> p{};
      l >> p[0] >> p[1] >> p[2];
      m.positions.push_back(p);
    } else if (tag == "f") {
      std::array<uint32_t, 3> t{};
      for (uint32_t& i : t) {
        std::string corner;
        l >> corner;
        i = static_cast<uint32_t>(std::stoul(corner.substr(0, corner.find('/')))) - 1;
      }
      m.triangles.push_back(t);
    }
  }
  return m;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST_F(CliNetwork, AFarViewExportIsTheSameFileEachTimeAndOpenOnlyAtTheViewsSides) {
  const std::string at = surface_at(16, 16);
  for (const char* name : {"far1.obj", "far2.obj"}) {
    ASSERT_EQ(run({"export", "--at", at, "--radius", "1", "--lod-distance", "1", "--lod-level", "2",
                   "--out", path(name)}),
              0)
        << err_.str();
    EXPECT_NE(out_.str().find("chunks of levels 0-2"), std::string::npos) << out_.str();
  }
  const std::string first = read_file(path("far1.obj"));
  // The file does not depend on the order chunks arrived in (LodWelder's tests shuffle it).
  EXPECT_EQ(first, read_file(path("far2.obj")));

  // One welded mesh: an edge in one triangle only lies on the view's outer sides, which the
  // terrain reaches along x and z (no crack between chunks of different levels).
  const ObjMesh m = read_obj(first);
  ASSERT_GT(m.triangles.size(), 1000u);
  std::array<float, 2> lo{1e30f, 1e30f}, hi{-1e30f, -1e30f};
  for (const auto& p : m.positions)
    for (int k = 0; k < 2; ++k) {
      lo[k] = std::min(lo[k], p[2 * k]);
      hi[k] = std::max(hi[k], p[2 * k]);
    }
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) ++edges[std::minmax(t[k], t[(k + 1) % 3])];
  const auto on_side = [&](uint32_t v) {
    const auto& p = m.positions[v];
    for (int k = 0; k < 2; ++k)
      if (std::fabs(p[2 * k] - lo[k]) < 1e-3f || std::fabs(p[2 * k] - hi[k]) < 1e-3f) return true;
    return false;
  };
  size_t open = 0;
  for (const auto& [e, count] : edges) {
    EXPECT_LE(count, 2) << "edge " << e.first << "-" << e.second;
    if (count == 1) {
      ++open;
      EXPECT_TRUE(on_side(e.first) && on_side(e.second))
          << "an open edge inside the view at (" << m.positions[e.first][0] << ", "
          << m.positions[e.first][1] << ", " << m.positions[e.first][2] << ")";
    }
  }
  EXPECT_GT(open, 0u) << "the terrain reaches the view's sides";
}

uint32_t u32(const std::vector<uint8_t>& b, size_t at) {
  return b[at] | b[at + 1] << 8 | b[at + 2] << 16 | static_cast<uint32_t>(b[at + 3]) << 24;
}

TEST_F(CliNetwork, ExportMatchesTheServersMeshesAndWritesAValidGlb) {
  const std::string at = surface_at(16, 16);
  ASSERT_EQ(run({"export", "--at", at, "--radius", "1", "--out", path("region.glb")}), 0)
      << err_.str();
  // What a plain client receives for the same view.
  client::Client c;
  c.connect("127.0.0.1", server_->port(), 5s);
  c.handshake("checker", 5s);
  const auto p = world::TerrainGenerator(1).height_at(16, 16);
  c.send(client::make_set_view(16, p, 16, 1, 1));
  c.receive_view(1, 60s);
  size_t triangles = 0;
  for (const auto& [key, held] : c.chunks())
    triangles += proto::decode_mesh(held.encoding)->triangle_count();
  std::smatch match;
  const std::string text = out_.str();
  ASSERT_TRUE(std::regex_search(text, match,
                                std::regex("(\\d+) chunks: (\\d+) vertices, (\\d+) triangles")));
  EXPECT_EQ(std::stoul(match[1]), c.chunks().size());
  EXPECT_EQ(std::stoul(match[3]), triangles);
  const size_t vertices = std::stoul(match[2]);

  // GLB structure: header, JSON and BIN chunks, accessors inside the buffer.
  std::ifstream in(path("region.glb"), std::ios::binary);
  const std::vector<uint8_t> b((std::istreambuf_iterator<char>(in)), {});
  ASSERT_GE(b.size(), 28u);
  EXPECT_EQ(u32(b, 0), 0x46546C67u);  // "glTF"
  EXPECT_EQ(u32(b, 4), 2u);
  EXPECT_EQ(u32(b, 8), b.size());
  const uint32_t json_len = u32(b, 12);
  EXPECT_EQ(u32(b, 16), 0x4E4F534Au);  // "JSON"
  EXPECT_EQ(json_len % 4, 0u);
  const std::string json(b.begin() + 20, b.begin() + 20 + json_len);
  const size_t bin_at = 20 + json_len;
  const uint32_t bin_len = u32(b, bin_at);
  EXPECT_EQ(u32(b, bin_at + 4), 0x004E4942u);  // "BIN\0"
  EXPECT_EQ(bin_at + 8 + bin_len, b.size());
  ASSERT_TRUE(
      std::regex_search(json, match, std::regex("\"buffers\":\\[\\{\"byteLength\":(\\d+)")));
  const size_t buffer_len = std::stoul(match[1]);
  EXPECT_LE(buffer_len, bin_len);
  const std::regex view("\\{\"buffer\":0,\"byteOffset\":(\\d+),\"byteLength\":(\\d+)");
  size_t views = 0;
  for (auto it = std::sregex_iterator(json.begin(), json.end(), view); it != std::sregex_iterator();
       ++it, ++views) {
    EXPECT_LE(std::stoul((*it)[1]) + std::stoul((*it)[2]), buffer_len)
        << "buffer view outside the buffer";
  }
  EXPECT_EQ(views, 4u);
  ASSERT_TRUE(std::regex_search(
      json, match,
      std::regex(
          "\"count\":(\\d+),\"type\":\"VEC3\",\"min\":\\[([^\\]]+)\\],\"max\":\\[([^\\]]+)\\]")));
  EXPECT_EQ(std::stoul(match[1]), vertices);
  // Accessor bounds: the region's chunks, and the positions inside them.
  std::vector<float> lo, hi;
  for (auto s : {match[2].str(), match[3].str()}) {
    std::replace(s.begin(), s.end(), ',', ' ');
    std::istringstream v(s);
    auto& dst = lo.empty() ? lo : hi;
    for (float f; v >> f;) dst.push_back(f);
  }
  ASSERT_EQ(lo.size(), 3u);
  ASSERT_EQ(hi.size(), 3u);
  const float* pos = reinterpret_cast<const float*>(b.data() + bin_at + 8);
  for (size_t v = 0; v < vertices; ++v) {
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(pos[3 * v + a], lo[a]);
      ASSERT_LE(pos[3 * v + a], hi[a]);
    }
  }
  EXPECT_LT(lo[0], 16.0f + 64);
  EXPECT_GT(hi[0], 16.0f - 64);
  // Indices in range, three different ones, within one cell: the view's sphere leaves
  // chunks of the box missing, and faces on their faces once pointed at vertex 0.
  const uint32_t* idx = reinterpret_cast<const uint32_t*>(b.data() + bin_at + 8 + vertices * 36);
  for (size_t t = 0; t < triangles * 3; t += 3) {
    for (int k = 0; k < 3; ++k) ASSERT_LT(idx[t + k], vertices);
    ASSERT_TRUE(idx[t] != idx[t + 1] && idx[t + 1] != idx[t + 2] && idx[t] != idx[t + 2])
        << "triangle " << t / 3;
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(std::fabs(pos[3 * idx[t + k] + a] - pos[3 * idx[t + (k + 1) % 3] + a]), 1.0f)
            << "triangle " << t / 3;
      }
  }

  for (const char* ext : {".obj", ".ply"}) {
    EXPECT_EQ(
        run({"export", "--at", at, "--radius", "1", "--out", path(std::string("region") + ext)}), 0)
        << err_.str();
  }
  EXPECT_EQ(run({"export", "--at", at, "--out", path("region.stl")}), 1) << "unknown extension";
}

}  // namespace
}  // namespace vox::cli

namespace vox::cli {
namespace {

TEST_F(CliNetwork, SliceWritesSvgWhoseContoursCloseOrEndAtTheBorder) {
  const float y = world::TerrainGenerator(1).height_at(300, 300);
  ASSERT_EQ(run({"slice", "--y", std::to_string(y), "--at", "300,300", "--radius", "1", "--levels",
                 "6", "--out", path("map.svg")}),
            0)
      << err_.str();
  std::ifstream in(path("map.svg"));
  const std::string svg((std::istreambuf_iterator<char>(in)), {});
  ASSERT_EQ(svg.rfind("<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 ", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  std::smatch match;
  ASSERT_TRUE(std::regex_search(svg, match, std::regex("viewBox=\"0 0 (\\d+) (\\d+)\"")));
  const float size = std::stof(match[1]);
  // Parsed by hand: std::regex recurses per character and overflows the stack on long paths.
  size_t paths = 0, segments = 0;
  for (size_t at = svg.find("<path "); at != std::string::npos;
       at = svg.find("<path ", at + 1), ++paths) {
    EXPECT_NE(svg.find("stroke=\"#", at), std::string::npos);
    const size_t d = svg.find(" d=\"", at) + 4;
    const size_t end = svg.find('"', d);
    std::istringstream tokens(svg.substr(d, end - d));
    std::map<std::string, int> degree;
    for (std::string m, y1, l, y2; tokens >> m >> y1 >> l >> y2; ++segments) {
      ASSERT_EQ(m[0], 'M');
      ASSERT_EQ(l[0], 'L');
      ++degree[m.substr(1) + " " + y1];
      ++degree[l.substr(1) + " " + y2];
    }
    for (const auto& [point, n] : degree) {
      if (n % 2 == 0) continue;  // inside a contour: joined on both sides
      std::istringstream xy(point);
      float x = 0, z = 0;
      xy >> x >> z;
      EXPECT_TRUE(x == 0 || z == 0 || x == size || z == size)
          << "contour ends inside the map at " << point;
    }
  }
  EXPECT_EQ(paths, 6u);
  EXPECT_GT(segments, 10u);
}

}  // namespace
}  // namespace vox::cli
