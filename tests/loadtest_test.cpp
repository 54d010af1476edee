// A short load test (20 players, 5 s) against a real voxeld: no errors, and every
// player's meshes equal what a fresh client receives (--verify).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include "tests/server_process.hpp"

namespace {

// Sanitizer builds run client and server several times slower: fewer players there.
#ifdef VOXEL_SANITIZED
constexpr int kPlayers = 8;
#else
constexpr int kPlayers = 20;
#endif

TEST(LoadTest, TwentyPlayersFiveSecondsWithoutErrorsAndVerified) {
  vox::test::ServerProcess server;
  const std::string json = (std::filesystem::temp_directory_path() / ("loadtest_" + std::to_string(::getpid()) + ".json")).string();
  const std::string cmd = std::string(VOXEL_LOADTEST_PATH) + " --server 127.0.0.1:" + std::to_string(server.port()) +
                          " --players " + std::to_string(kPlayers) + " --duration 5 --ramp 1 --edit-rate 1 --view-radius 3 --verify --json " + json +
                          " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  std::ifstream in(json);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::filesystem::remove(json);
  for (const std::string& key : {"\"players\":" + std::to_string(kPlayers), std::string("\"errors\":0"),
                                 std::string("\"disconnects\":0"), std::string("\"decode_failures\":0"),
                                 std::string("\"verified\":true"), std::string("\"verify_mismatches\":0"),
                                 "\"players_connected\":" + std::to_string(kPlayers)}) {
    EXPECT_NE(text.find(key), std::string::npos) << key << " in " << text;
  }
  for (const char* key : {"duration_s", "edits_sent", "edit_to_result_ms", "edit_to_delta_ms", "bytes_per_player_per_s"}) {
    EXPECT_NE(text.find(key), std::string::npos) << key;
  }
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"edits_sent\":(\\d+)")));
  EXPECT_GT(std::stoul(m[1]), static_cast<unsigned long>(kPlayers));
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"edit_to_delta_ms\":\\{\"p50\":([0-9.]+),\"p95\":([0-9.]+),\"p99\":([0-9.]+),\"max\":([0-9.]+),\"count\":(\\d+)")));
  EXPECT_GT(std::stoul(m[5]), 0u) << "some edits' deltas were measured";
}

}  // namespace
