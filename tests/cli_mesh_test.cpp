#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "client-cli/commands.hpp"
#include "tests/temp_dir.hpp"

namespace vox::cli {
namespace {

namespace fs = std::filesystem;

class CliMesh : public ::testing::Test {
 protected:
  void SetUp() override { dir_.emplace("cli_mesh"); }

  std::string path(const std::string& name) const { return (*dir_ / name).string(); }
  void write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name), std::ios::binary) << text;
  }
  int run(std::vector<std::string> args) {
    out_.str("");
    err_.str("");
    return run_cli(args, out_, err_);
  }
  // Nothing but the inputs is left in the directory (no partial or temporary output).
  size_t files_in_dir() const {
    return static_cast<size_t>(
        std::distance(fs::directory_iterator(dir_->path()), fs::directory_iterator()));
  }

  // A sphere of radius 3 in a 9^3 text volume, values in [-1, 1] like the seed's files.
  std::string sphere_text(bool bourke_convention) const {
    std::ostringstream s;
    s << "9 9 9\n";
    for (int z = 0; z < 9; ++z)
      for (int y = 0; y < 9; ++y)
        for (int x = 0; x < 9; ++x) {
          const float d = 3.0f - std::sqrt(float((x - 4.2) * (x - 4.2) + (y - 3.9) * (y - 3.9) +
                                                 (z - 4.1) * (z - 4.1)));
          const float v = std::clamp(d / 3.0f, -1.0f, 1.0f);
          s << (bourke_convention ? -v : v) << ' ';
        }
    return s.str();
  }

  std::optional<test::TempDir> dir_;  // optional: a test may start over in a fresh one
  std::ostringstream out_, err_;
};

TEST_F(CliMesh, TextVolumeToSeedFormatRoundTrips) {
  write("sphere.txt", sphere_text(false));
  ASSERT_EQ(run({"mesh", path("sphere.txt"), "--out", path("out.txt")}), 0) << err_.str();
  EXPECT_NE(out_.str().find("triangles"), std::string::npos);
  std::ifstream in(path("out.txt"));
  size_t vertices = 0, triangles = 0;
  in >> vertices;
  for (size_t i = 0; i < 3 * vertices; ++i) {
    float v;
    ASSERT_TRUE(in >> v);
  }
  in >> triangles;
  EXPECT_GT(vertices, 20u);
  EXPECT_GT(triangles, 20u);
  for (size_t i = 0; i < 3 * triangles; ++i) {
    size_t index;
    ASSERT_TRUE(in >> index);
    EXPECT_LT(index, vertices);
  }
}

TEST_F(CliMesh, InvertMeshesTheSeedsConventionTheSame) {
  write("scan.txt", sphere_text(false));
  write("bourke.txt", sphere_text(true));
  ASSERT_EQ(run({"mesh", path("scan.txt"), "--out", path("a.txt")}), 0) << err_.str();
  ASSERT_EQ(run({"mesh", path("bourke.txt"), "--out", path("b.txt"), "--invert"}), 0) << err_.str();
  auto slurp = [&](const std::string& name) {
    std::ifstream in(path(name));
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(slurp("a.txt"), slurp("b.txt"));
  ASSERT_EQ(run({"mesh", path("bourke.txt"), "--out", path("c.txt")}), 0) << err_.str();
  EXPECT_NE(slurp("a.txt"), slurp("c.txt")) << "without --invert the solid side flips";
}

TEST_F(CliMesh, RawFloatVolumeWithDimsAndPlyOutput) {
  std::vector<float> values(16 * 16 * 16);
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x)
        values[x + 16 * (y + 16 * z)] = 7.5f - static_cast<float>(y) + 0.1f * x;  // a slope
  std::ofstream(path("vol.raw"), std::ios::binary)
      .write(reinterpret_cast<const char*>(values.data()), values.size() * 4);
  ASSERT_EQ(run({"mesh", path("vol.raw"), "--dims", "16,16,16", "--out", path("out.ply"),
                 "--threads", "2"}),
            0)
      << err_.str();
  std::ifstream in(path("out.ply"), std::ios::binary);
  std::string magic;
  std::getline(in, magic);
  EXPECT_EQ(magic, "ply");
}

struct BadCase {
  const char* name;
  std::string content;  // empty: file not created
  std::vector<std::string> extra;
  const char* message;  // expected in the error line
};

TEST_F(CliMesh, BadInputGivesOneLineErrorAndNoOutputFile) {
  const std::vector<BadCase> cases = {
      {"missing file", "", {}, "cannot open"},
      {"short file", "3 3 3\n1 2 3", {}, "expected 27 values, the file has room for at most 3"},
      {"short by one", "2 2 2\n1 2 3 4 5 6 7   ", {}, "expected 8 values, found 7"},
      // A header is not trusted before the file is: this one asked for 8.6 GB.
      {"huge header",
       "1290 1290 1290\n0",
       {},
       "expected 2146689000 values, the file has room for at most 1"},
      {"non-number", "2 2 2\n1 2 3 x 5 6 7 8", {}, "value 3 is not a number"},
      {"nan", "2 2 2\n1 2 3 nan 5 6 7 8", {}, "value 3 is not finite"},
      {"bad header", "2 two 2\n", {}, "ydim is not an integer"},
      {"empty", " ", {}, "missing xdim"},
      {"flat dims", "1 2 2\n1 2 3 4", {}, "at least 2 samples"},
      {"extra values", "2 2 2\n1 2 3 4 5 6 7 8 9", {}, "more than the 8 values"},
      {"raw size mismatch", "abcd", {"--dims", "2,2,2"}, "needs 32 bytes, file has 4"},
      {"bad dims flag", "abcd", {"--dims", "2,x,2"}, "--dims must be X,Y,Z"},
      {"huge dims", "abcd", {"--dims", "100000,100000,100000"}, "too large"},
  };
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.name);
    dir_.emplace("cli_mesh");  // each case starts in an empty directory
    if (!c.content.empty()) write("in.vol", c.content);
    std::vector<std::string> args = {"mesh", path("in.vol"), "--out", path("out.obj")};
    args.insert(args.end(), c.extra.begin(), c.extra.end());
    EXPECT_NE(run(args), 0);
    const std::string err = err_.str();
    EXPECT_NE(err.find(c.message), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_FALSE(fs::exists(path("out.obj")));
    EXPECT_EQ(files_in_dir(), c.content.empty() ? 0u : 1u);
  }
}

TEST_F(CliMesh, UnknownOutputExtensionIsRefusedBeforeMeshing) {
  write("sphere.txt", sphere_text(false));
  EXPECT_EQ(run({"mesh", path("sphere.txt"), "--out", path("out.stl")}), 1);
  EXPECT_NE(err_.str().find("unknown output format"), std::string::npos);
  EXPECT_EQ(files_in_dir(), 1u);
}

TEST_F(CliMesh, UsageErrorsExitTwo) {
  EXPECT_EQ(run({"mesh"}), 2);
  EXPECT_EQ(run({"mesh", path("x"), "--out", path("y.obj"), "--iso", "nan"}), 2);
  EXPECT_EQ(run({"frobnicate"}), 2);
  EXPECT_EQ(run({"mesh", "--help"}), 0);
  EXPECT_NE(out_.str().find("--invert"), std::string::npos);
}

TEST_F(CliMesh, ExecutableReportsErrorsThroughExitCode) {
  const std::string cmd = std::string(VOXEL_CLI_PATH) + " mesh " + path("nothing.txt") + " --out " +
                          path("o.obj") + " 2>" + path("err.log");
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream err(path("err.log"));
  std::string line;
  std::getline(err, line);
  EXPECT_NE(line.find("cannot open"), std::string::npos) << line;
}

// A mesh file read back: positions snapped to the 1/1024 grid the mesher puts them on
// (the text formats print 6 digits, exact enough below 100), triangles as index triples.
struct MeshFileContents {
  std::vector<std::array<int64_t, 3>> positions;
  std::vector<std::array<uint32_t, 3>> triangles;
};

std::array<int64_t, 3> snapped(double x, double y, double z) {
  return {std::llround(x * 1024), std::llround(y * 1024), std::llround(z * 1024)};
}

MeshFileContents read_txt(const std::string& file) {
  MeshFileContents m;
  std::ifstream in(file);
  size_t n = 0;
  in >> n;
  for (size_t i = 0; i < n; ++i) {
    double x, y, z;
    in >> x >> y >> z;
    m.positions.push_back(snapped(x, y, z));
  }
  in >> n;
  for (size_t i = 0; i < n; ++i) {
    uint32_t a, b, c;
    in >> a >> b >> c;
    m.triangles.push_back({a, b, c});
  }
  EXPECT_TRUE(in) << file;
  return m;
}

MeshFileContents read_obj(const std::string& file) {
  MeshFileContents m;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    double x, y, z;
    uint32_t a, b, c, na, nb, nc;
    if (std::sscanf(line.c_str(), "v %lf %lf %lf", &x, &y, &z) == 3)
      m.positions.push_back(snapped(x, y, z));
    if (std::sscanf(line.c_str(), "f %u//%u %u//%u %u//%u", &a, &na, &b, &nb, &c, &nc) == 6) {
      m.triangles.push_back({a - 1, b - 1, c - 1});
    }
  }
  return m;
}

MeshFileContents read_ply(const std::string& file) {
  MeshFileContents m;
  std::ifstream in(file, std::ios::binary);
  size_t vertices = 0, faces = 0;
  for (std::string line; std::getline(in, line) && line != "end_header";) {
    std::sscanf(line.c_str(), "element vertex %zu", &vertices);
    std::sscanf(line.c_str(), "element face %zu", &faces);
  }
  for (size_t i = 0; i < vertices; ++i) {
    float v[6];
    uint8_t material;
    in.read(reinterpret_cast<char*>(v), sizeof v).read(reinterpret_cast<char*>(&material), 1);
    m.positions.push_back(snapped(v[0], v[1], v[2]));
  }
  for (size_t i = 0; i < faces; ++i) {
    uint8_t count;
    std::array<uint32_t, 3> t;
    in.read(reinterpret_cast<char*>(&count), 1).read(reinterpret_cast<char*>(t.data()), 12);
    EXPECT_EQ(count, 3);
    m.triangles.push_back(t);
  }
  EXPECT_TRUE(in) << file;
  return m;
}

// Integer samples, iso 0, as in a scan: a sphere (value R^2 - |p - c|^2, exactly 0 wherever
// |p - c|^2 = R^2), a box (value 6 - max |p - c|, 0 on whole planes) and a block of noise
// in -1..3 (zeros among solid samples: surfaces that shrink to a point), all across the
// chunk faces at 32, so that many vertices sit on samples and many table triangles have
// zero area.
std::string integer_volume_text() {
  std::ostringstream s;
  const int n = 48;
  s << n << ' ' << n << ' ' << n << '\n';
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int sphere = 100 - ((x - 31) * (x - 31) + (y - 30) * (y - 30) + (z - 33) * (z - 33));
        const int box = 6 - std::max({std::abs(x - 32), std::abs(y - 12), std::abs(z - 12)});
        const uint32_t h = static_cast<uint32_t>(x + n * (y + n * z)) * 2654435761u;
        const bool in_noise = x >= 26 && x < 40 && y >= 24 && y < 40 && z < 20;
        s << (in_noise ? static_cast<int>((h >> 16) % 5) - 1 : std::max(sphere, box)) << ' ';
      }
  return s.str();
}

// Issue 12 item 8: vertices whose every triangle was dropped as zero-area were still
// written (8,889 of 1.15 M on an MRI volume with integer samples).
TEST_F(CliMesh, EveryWrittenVertexIsUsedWhenSamplesLieOnTheIsoLevel) {
  write("ints.txt", integer_volume_text());
  for (const std::string ext : {".obj", ".ply", ".txt"}) {
    SCOPED_TRACE(ext);
    ASSERT_EQ(run({"mesh", path("ints.txt"), "--out", path("out" + ext), "--threads", "2"}), 0)
        << err_.str();
    const MeshFileContents m = ext == ".obj"   ? read_obj(path("out.obj"))
                               : ext == ".ply" ? read_ply(path("out.ply"))
                                               : read_txt(path("out.txt"));
    ASSERT_GT(m.triangles.size(), 1000u);
    std::vector<bool> used(m.positions.size(), false);
    size_t out_of_range = 0, zero_area = 0;
    for (const auto& t : m.triangles) {
      if (t[0] >= used.size() || t[1] >= used.size() || t[2] >= used.size()) {
        ++out_of_range;
        continue;
      }
      const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
      const int64_t u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
                    w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      zero_area +=
          (u[1] * w[2] == u[2] * w[1] && u[2] * w[0] == u[0] * w[2] && u[0] * w[1] == u[1] * w[0])
              ? 1
              : 0;
      for (uint32_t v : t) used[v] = true;
    }
    EXPECT_EQ(out_of_range, 0u);
    EXPECT_EQ(zero_area, 0u) << "of " << m.triangles.size() << " triangles";
    EXPECT_EQ(std::count(used.begin(), used.end(), false), 0)
        << "unused of " << m.positions.size() << " vertices";
  }
}

// Issue 15: vertices of one chunk at one sample (a sample exactly on the iso level) were
// written once per cut edge meeting there, up to six copies of one grid point.
TEST_F(CliMesh, NoTwoVerticesShareAPositionWhenSamplesLieOnTheIsoLevel) {
  write("ints.txt", integer_volume_text());
  ASSERT_EQ(run({"mesh", path("ints.txt"), "--out", path("out.ply"), "--threads", "2"}), 0)
      << err_.str();
  const MeshFileContents m = read_ply(path("out.ply"));
  ASSERT_GT(m.positions.size(), 1000u);
  std::vector<std::array<int64_t, 3>> sorted = m.positions;
  std::sort(sorted.begin(), sorted.end());
  const size_t distinct =
      static_cast<size_t>(std::unique(sorted.begin(), sorted.end()) - sorted.begin());
  EXPECT_EQ(distinct, m.positions.size());
}

TEST_F(CliMesh, DemoWritesTerrainMesh) {
  ASSERT_EQ(run({"demo", "--radius", "1", "--out", path("demo.obj")}), 0) << err_.str();
  EXPECT_TRUE(fs::exists(path("demo.obj")));
  EXPECT_GT(fs::file_size(path("demo.obj")), 1000u);
}

}  // namespace
}  // namespace vox::cli
