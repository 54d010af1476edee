#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "client-cli/commands.hpp"

namespace vox::cli {
namespace {

namespace fs = std::filesystem;

class CliMesh : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("voxel_cli_test_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write(const std::string& name, const std::string& text) const { std::ofstream(path(name), std::ios::binary) << text; }
  int run(std::vector<std::string> args) {
    out_.str("");
    err_.str("");
    return run_cli(args, out_, err_);
  }
  // Nothing but the inputs is left in the directory (no partial or temporary output).
  size_t files_in_dir() const { return static_cast<size_t>(std::distance(fs::directory_iterator(dir_), fs::directory_iterator())); }

  // A sphere of radius 3 in a 9^3 text volume, values in [-1, 1] like the seed's files.
  std::string sphere_text(bool bourke_convention) const {
    std::ostringstream s;
    s << "9 9 9\n";
    for (int z = 0; z < 9; ++z)
      for (int y = 0; y < 9; ++y)
        for (int x = 0; x < 9; ++x) {
          const float d = 3.0f - std::sqrt(float((x - 4.2) * (x - 4.2) + (y - 3.9) * (y - 3.9) + (z - 4.1) * (z - 4.1)));
          const float v = std::clamp(d / 3.0f, -1.0f, 1.0f);
          s << (bourke_convention ? -v : v) << ' ';
        }
    return s.str();
  }

  fs::path dir_;
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
      for (int x = 0; x < 16; ++x) values[x + 16 * (y + 16 * z)] = 7.5f - static_cast<float>(y) + 0.1f * x;  // a slope
  std::ofstream(path("vol.raw"), std::ios::binary).write(reinterpret_cast<const char*>(values.data()), values.size() * 4);
  ASSERT_EQ(run({"mesh", path("vol.raw"), "--dims", "16,16,16", "--out", path("out.ply"), "--threads", "2"}), 0)
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
      {"huge header", "1290 1290 1290\n0", {}, "expected 2146689000 values, the file has room for at most 1"},
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
    fs::remove_all(dir_);
    fs::create_directories(dir_);
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
  const std::string cmd = std::string(VOXEL_CLI_PATH) + " mesh " + path("nothing.txt") + " --out " + path("o.obj") +
                          " 2>" + path("err.log");
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream err(path("err.log"));
  std::string line;
  std::getline(err, line);
  EXPECT_NE(line.find("cannot open"), std::string::npos) << line;
}

TEST_F(CliMesh, DemoWritesTerrainMesh) {
  ASSERT_EQ(run({"demo", "--radius", "1", "--out", path("demo.obj")}), 0) << err_.str();
  EXPECT_TRUE(fs::exists(path("demo.obj")));
  EXPECT_GT(fs::file_size(path("demo.obj")), 1000u);
}

}  // namespace
}  // namespace vox::cli
