// A short load test (20 players, 5 s) against a real voxeld: no errors, and every
// player's meshes equal what a fresh client receives (--verify). Then --attack: its MIX
// parser, the RSS sampler, and a short run with every kind of attacker. And the players'
// signed tokens (--token-key).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "client/asio.hpp"
#include "loadtest/attack_mix.hpp"
#include "loadtest/player_tokens.hpp"
#include "loadtest/server_sampler.hpp"
#include "loadtest/sweep.hpp"
#include "server/auth/player_token.hpp"
#include "tests/server_process.hpp"
#include "tests/temp_dir.hpp"

namespace {

// Sanitizer builds run client and server several times slower: fewer players there.
#ifdef VOXEL_SANITIZED
constexpr int kPlayers = 8;
#else
constexpr int kPlayers = 20;
#endif

// Runs voxel-loadtest against `server` with `args` and --json; the exit code (-1: it did
// not exit normally) and the JSON it wrote.
struct TesterRun {
  int exit_code = -1;
  std::string json;
};
TesterRun run_tester(const vox::test::ServerProcess& server, const std::string& args) {
  const vox::test::TempDir tmp("loadtest");
  const std::string json = (tmp / "run.json").string();
  const std::string cmd = std::string(VOXEL_LOADTEST_PATH) +
                          " --server 127.0.0.1:" + std::to_string(server.port()) + " " + args +
                          " --json " + json + " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  TesterRun run;
  if (WIFEXITED(status)) run.exit_code = WEXITSTATUS(status);
  std::ifstream in(json);
  run.json.assign(std::istreambuf_iterator<char>(in), {});
  return run;
}

TEST(LoadTest, TwentyPlayersFiveSecondsWithoutErrorsAndVerified) {
  // --verify compares with a fresh client after a quiet spell; a per-player load budget
  // stretches a view's loading past such spells under the sanitizers, so it is off here
  // (the load budget has its own tests).
  vox::test::ServerProcess server({"--load-budget", "0"});
  const TesterRun run =
      run_tester(server, "--players " + std::to_string(kPlayers) +
                             " --duration 5 --ramp 1 --edit-rate 1 --view-radius 3 --verify");
  EXPECT_EQ(run.exit_code, 0);
  const std::string& text = run.json;
  for (const std::string& key :
       {"\"players\":" + std::to_string(kPlayers), std::string("\"errors\":0"),
        std::string("\"disconnects\":0"), std::string("\"decode_failures\":0"),
        std::string("\"verified\":true"), std::string("\"verify_mismatches\":0"),
        "\"players_connected\":" + std::to_string(kPlayers)}) {
    EXPECT_NE(text.find(key), std::string::npos) << key << " in " << text;
  }
  for (const char* key : {"duration_s", "edits_sent", "edit_to_result_ms", "edit_to_delta_ms",
                          "bytes_per_player_per_s"}) {
    EXPECT_NE(text.find(key), std::string::npos) << key;
  }
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"edits_sent\":(\\d+)")));
  EXPECT_GT(std::stoul(m[1]), static_cast<unsigned long>(kPlayers));
  ASSERT_TRUE(
      std::regex_search(text, m,
                        std::regex("\"edit_to_delta_ms\":\\{\"p50\":([0-9.]+),\"p95\":([0-9.]+),"
                                   "\"p99\":([0-9.]+),\"p999\":([0-9.]+),\"max\":([0-9.]+),"
                                   "\"count\":(\\d+)")));
  EXPECT_GT(std::stoul(m[6]), 0u) << "some edits' deltas were measured";
}

// --reconnect: the node a player is on dies (kill -9); the player connects to the next
// server (--more-servers), gets its view again, and resends its unanswered edits with their
// edit ids. The run reports the time to reconnect and to a complete view, and no error.
TEST(LoadTest, PlayersWhoseServerDiesReconnectToTheNextAndGetTheirViewBack) {
  auto a = std::make_unique<vox::test::ServerProcess>(std::vector<std::string>{"--in-memory"});
  vox::test::ServerProcess b({"--in-memory"});
  const pid_t a_pid = a->pid();
  std::thread killer([a_pid] {
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));
    ::kill(a_pid, SIGKILL);
  });
  const TesterRun run =
      run_tester(*a,
                 "--players 6 --duration 4 --ramp 0.5 --edit-rate 2 --view-radius 2 --reconnect "
                 "--more-servers 127.0.0.1:" +
                     std::to_string(b.port()));
  killer.join();
  const std::string& text = run.json;
  EXPECT_NE(text.find("\"errors\":0"), std::string::npos) << text;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      text, m,
      std::regex("\"reconnect_view_ms\":\\{\"p50\":[0-9.]+,\"p95\":[0-9.]+,"
                 "\"p99\":[0-9.]+,\"p999\":[0-9.]+,\"max\":([0-9.]+),\"count\":(\\d+)")))
      << text;
  EXPECT_EQ(std::stoul(m[2]), 3u) << "the three players on the killed server got their views back";
  EXPECT_LT(std::stod(m[1]), 10000.0);
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"disconnects\":(\\d+)")));
  EXPECT_GE(std::stoul(m[1]), 3u);
}

// voxeld's /metrics as name -> value (a blocking HTTP/1.0 GET on 127.0.0.1).
std::map<std::string, double> scrape_metrics(uint16_t port) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket socket(io);
  socket.connect({boost::asio::ip::make_address("127.0.0.1"), port});
  const std::string request = "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  boost::asio::write(socket, boost::asio::buffer(request));
  std::string response;
  boost::system::error_code ec;
  boost::asio::read(socket, boost::asio::dynamic_buffer(response), ec);  // to the close
  std::map<std::string, double> out;
  std::istringstream lines(response.substr(std::min(response.size(), response.find("\r\n\r\n"))));
  for (std::string line; std::getline(lines, line);) {
    const size_t space = line.rfind(' ');
    if (line.empty() || line[0] == '#' || space == std::string::npos) continue;
    out[line.substr(0, space)] = std::atof(line.c_str() + space + 1);
  }
  return out;
}

// --websocket: the same players over voxeld's HTTP port (GET /ws, one Envelope per binary
// message), each from its own address; the verifier's fresh client stays on TCP, so it
// also checks that both transports carry the same meshes.
TEST(LoadTest, PlayersOverWebSocketAnswerEditsDecodeMeshesAndVerify) {
  vox::test::ServerProcess server(
      {"--load-budget", "0", "--http-port", "auto", "--metrics-port", "0"});
  const int players = 5;
  const TesterRun run =
      run_tester(server, "--websocket 127.0.0.1:" + std::to_string(server.http_port()) +
                             " --players " + std::to_string(players) +
                             " --duration 3 --ramp 0.5 --edit-rate 2 --view-radius 3"
                             " --spread-addresses --verify");
  EXPECT_EQ(run.exit_code, 0);
  const std::string& text = run.json;
  for (const std::string& key :
       {"\"players_connected\":" + std::to_string(players), std::string("\"errors\":0"),
        std::string("\"disconnects\":0"), std::string("\"decode_failures\":0"),
        std::string("\"verified\":true"), std::string("\"verify_mismatches\":0")}) {
    EXPECT_NE(text.find(key), std::string::npos) << key << " in " << text;
  }
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(text, m, std::regex("\"edit_to_result_ms\":\\{[^}]*\"count\":(\\d+)")));
  EXPECT_GT(std::stoul(m[1]), 0u) << "edits were answered";
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"chunks_streamed\":(\\d+)")));
  EXPECT_GT(std::stoul(m[1]), 0u) << "meshes were decoded";
  // The players came over WebSocket, not over the TCP port (the verifier's clients did).
  auto metrics = scrape_metrics(server.metrics_port());
  EXPECT_EQ(metrics["voxeld_websocket_upgrades_total"], players);
}

TEST(LoadTest, ABadWebSocketAddressIsAUsageErrorWithExitCode2) {
  for (const char* value : {"127.0.0.1", "127.0.0.1:0", "127.0.0.1:70000", "localhost:80", ":80",
                            "127.0.0.1:80x", ""}) {
    const std::string cmd = std::string(VOXEL_LOADTEST_PATH) + " --websocket '" + value +
                            "' --players 1 --duration 1 > /dev/null 2>&1";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << value;
    EXPECT_EQ(WEXITSTATUS(status), 2) << value;
  }
  const std::string remote = std::string(VOXEL_LOADTEST_PATH) +
                             " --websocket 10.0.0.1:80 --spread-addresses > /dev/null 2>&1";
  const int status = std::system(remote.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2) << "--spread-addresses needs a loopback --websocket";
}

}  // namespace

// ---- --attack: the MIX parser, the RSS sampler, and a short run under attack ------------

namespace {

using vox::loadtest::AttackKind;
using vox::loadtest::parse_attack_mix;

TEST(AttackMix, ParsesEveryKindWithItsCount) {
  const auto mix = parse_attack_mix("flood:3,heavy:2,squat:2,slow:2,empty:1");
  ASSERT_TRUE(mix) << mix.error();
  EXPECT_EQ(mix->count(AttackKind::flood), 3);
  EXPECT_EQ(mix->count(AttackKind::heavy), 2);
  EXPECT_EQ(mix->count(AttackKind::squat), 2);
  EXPECT_EQ(mix->count(AttackKind::slow), 2);
  EXPECT_EQ(mix->count(AttackKind::empty), 1);
  EXPECT_EQ(mix->connections(), 3 + 2 + 2 * vox::loadtest::kSquatGroupSize + 2 + 1);
  EXPECT_EQ(mix->to_string(), "flood:3,heavy:2,squat:2,slow:2,empty:1");
}

TEST(AttackMix, AcceptsAnyOrderZeroAndTheLimit) {
  const auto mix = parse_attack_mix("empty:1000,flood:0,slow:7");
  ASSERT_TRUE(mix) << mix.error();
  EXPECT_EQ(mix->count(AttackKind::empty), 1000);
  EXPECT_EQ(mix->count(AttackKind::flood), 0);
  EXPECT_EQ(mix->count(AttackKind::slow), 7);
  EXPECT_EQ(mix->count(AttackKind::heavy), 0);
  EXPECT_EQ(mix->to_string(), "slow:7,empty:1000");  // canonical order, zeros left out
  const auto none = parse_attack_mix("flood:0");
  ASSERT_TRUE(none);
  EXPECT_TRUE(none->empty());
}

TEST(AttackMix, RefusesEveryMalformedMix) {
  for (const char* bad : {"",
                          ",",
                          "flood",
                          "flood:",
                          ":3",
                          "flood:-1",
                          "flood:+1",
                          "flood:1001",
                          "flood:99999",
                          "flood:1x",
                          "flood: 1",
                          " flood:1",
                          "flood:0x10",
                          "flood:1:2",
                          "flood:3,",
                          ",flood:3",
                          "flood:3,,heavy:1",
                          "flood:3,flood:1",
                          "bogus:1",
                          "FLOOD:1",
                          "flood:3;heavy:1"}) {
    const auto mix = parse_attack_mix(bad);
    EXPECT_FALSE(mix) << "'" << bad << "' was accepted";
    if (!mix) {
      EXPECT_FALSE(mix.error().empty()) << bad;
    }
  }
  EXPECT_NE(parse_attack_mix("bogus:1").error().find("bogus"), std::string::npos);
  EXPECT_NE(parse_attack_mix("flood:1,flood:2").error().find("twice"), std::string::npos);
}

TEST(ServerSampler, ParsesVmRssAndRefusesWhatIsNotIt) {
  EXPECT_EQ(
      vox::loadtest::parse_vm_rss_kib("Name:\tvoxeld\nVmPeak:\t  900 kB\nVmRSS:\t   12345 kB\n"
                                      "RssAnon:\t 100 kB\n"),
      12345u);
  EXPECT_FALSE(vox::loadtest::parse_vm_rss_kib("Name:\tkthreadd\nState:\tS\n"));
  EXPECT_FALSE(vox::loadtest::parse_vm_rss_kib("VmRSS:\t  12x kB\n"));
  EXPECT_FALSE(vox::loadtest::parse_vm_rss_kib(""));
}

TEST(ServerSampler, FindsOnlyTheListeningSocketOfThePort) {
  const std::string table =
      "  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout "
      "inode\n"
      "   0: 0100007F:1E61 0100007F:9C40 01 00000000:00000000 00:00000000 00000000  1000        0 "
      "111 1 0\n"
      "   1: 0100007F:1E62 00000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 "
      "222 1 0\n"
      "   2: 0100007F:1E61 00000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 "
      "333 1 0\n";
  EXPECT_EQ(vox::loadtest::find_listening_inode(table, 0x1E61), 333u);
  EXPECT_EQ(vox::loadtest::find_listening_inode(table, 0x1E62), 222u);
  EXPECT_FALSE(vox::loadtest::find_listening_inode(table, 0x1E63));
  EXPECT_FALSE(vox::loadtest::find_listening_inode("garbage\nmore garbage\n", 0x1E61));
}

TEST(ServerSampler, FindsThisProcessListeningOnLoopback) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor acceptor(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  EXPECT_EQ(vox::loadtest::find_listening_pid(acceptor.local_endpoint().port()), ::getpid());
  vox::loadtest::ServerSampler sampler(::getpid());
  sampler.sample();
  ASSERT_EQ(sampler.kib().size(), 1u);
  EXPECT_GT(sampler.kib().front(), 0.0);
  EXPECT_TRUE(sampler.cpu_percent().empty());  // a rate needs two readings
  // Burn 200 ms of CPU (20 clock ticks), then the second reading gives a share of a core.
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  volatile double x = 0;
  while (std::chrono::steady_clock::now() < until) x = x + 1e-9;
  sampler.sample();
  ASSERT_EQ(sampler.cpu_percent().size(), 1u);
  EXPECT_GT(sampler.cpu_percent().front(), 0.0);
}

TEST(CpuSampler, ReadsUtimePlusStimeEvenWhenTheCommandHoldsSpacesAndParentheses) {
  // Fields from 3 on: state ppid pgrp session tty tpgid flags minflt cminflt majflt
  // cmajflt utime stime ...
  const std::string tail = " S 1 2 3 4 5 6 7 8 9 10 1200 34 0 0 20 0 9 0 100\n";
  EXPECT_EQ(vox::loadtest::parse_cpu_ticks("4242 (voxeld)" + tail), 1234u);
  EXPECT_EQ(vox::loadtest::parse_cpu_ticks("4242 (a) b (c) d)" + tail), 1234u);
  EXPECT_FALSE(vox::loadtest::parse_cpu_ticks("4242 voxeld S 1 2"));
  EXPECT_FALSE(vox::loadtest::parse_cpu_ticks("4242 (voxeld) S 1 2 3"));
  EXPECT_FALSE(vox::loadtest::parse_cpu_ticks(""));
}

TEST(Soak, AMinuteAboveMaxP99OrMaxRssExitsOneAndGenerousLimitsExitZero) {
  vox::test::ServerProcess server;
  const std::string run = "--players 4 --duration 2 --ramp 0.5 --edit-rate 2 --view-radius 2";
  const TesterRun tight = run_tester(server, run + " --max-p99-ms 0.001");
  EXPECT_EQ(tight.exit_code, 1);
  EXPECT_NE(tight.json.find("\"per_minute\":[{\"minute\":1,"), std::string::npos) << tight.json;
  EXPECT_NE(tight.json.find("\"worst_second\":{"), std::string::npos);
  EXPECT_NE(tight.json.find("\"cpu_percent\":"), std::string::npos);
  EXPECT_EQ(run_tester(server, run + " --max-rss 1").exit_code, 1);
  EXPECT_EQ(run_tester(server, run + " --max-p99-ms 100000 --max-rss 100000").exit_code, 0);
}

TEST(Soak, LimitsThatAreNotPositiveAreUsageErrors) {
  for (const char* args : {" --max-p99-ms 0", " --max-rss -5", " --max-rss 10 --server-pid -1",
                           " --sweep 1,2 --max-p99-ms 100"}) {
    const std::string cmd = std::string(VOXEL_LOADTEST_PATH) + args + " > /dev/null 2>&1";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << args;
    EXPECT_EQ(WEXITSTATUS(status), 2) << args;
  }
}

TEST(AttackLoadTest, BadMixIsAUsageErrorWithExitCode2) {
  const std::string cmd =
      std::string(VOXEL_LOADTEST_PATH) + " --attack flood:2,bogus:1 > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
}

TEST(Sweep, CountsAreWholeNumbersInRangeAndNothingElse) {
  const auto ok = vox::loadtest::parse_sweep_counts("300,400,500");
  ASSERT_TRUE(ok);
  EXPECT_EQ(*ok, (std::vector<int>{300, 400, 500}));
  for (const char* bad : {"", "abc", "300,", ",300", "300,,400", "0", "10001", "-5", "3.5", "300 ",
                          "1e3", "99999999999999999999"}) {
    EXPECT_FALSE(vox::loadtest::parse_sweep_counts(bad)) << "'" << bad << "'";
  }
  std::string many;
  for (int i = 0; i < 65; ++i) {
    if (i > 0) many.push_back(',');
    many.push_back('1');
  }
  EXPECT_FALSE(vox::loadtest::parse_sweep_counts(many));
}

// `--sweep abc` aborted the tester (exit 134, an uncaught std::stoi exception).
TEST(Sweep, ABadCountIsAUsageErrorWithExitCode2NotAnAbort) {
  for (const char* args :
       {" --sweep abc", " --sweep 300,abc", " --sweep 0", " --sweep 100 --sweep-limit-ms 0"}) {
    const std::string cmd = std::string(VOXEL_LOADTEST_PATH) + args + " > /dev/null 2>&1";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << args;
    EXPECT_EQ(WEXITSTATUS(status), 2) << args;
  }
}

#ifdef VOXEL_SANITIZED
constexpr int kSweepLimitMs = 600;  // sanitizer builds run several times slower
#else
constexpr int kSweepLimitMs = 100;
#endif

TEST(Sweep, RunsEachCountAndExitsZeroOnlyWhenOneMetTheLimit) {
  // The sweep's mechanics, not the server's speed: no store (an fsync per batch), and a
  // limit a sanitizer build under a parallel ctest meets (it missed 100 ms once under TSan).
  vox::test::ServerProcess server({"--load-budget", "0", "--in-memory"});
  const std::string base = std::string(VOXEL_LOADTEST_PATH) +
                           " --server 127.0.0.1:" + std::to_string(server.port()) +
                           " --duration 1 --ramp 0.2 --view-radius 2 --sweep 2,3";
  const vox::test::TempDir tmp("sweep");
  const std::string out = (tmp / "sweep.out").string();
  int status = std::system(
      (base + " --sweep-limit-ms " + std::to_string(kSweepLimitMs) + " > " + out + " 2>/dev/null")
          .c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  std::ifstream in(out);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(text.find("players 2: "), std::string::npos) << text;
  EXPECT_NE(text.find("players 3: "), std::string::npos) << text;
  EXPECT_NE(text.find("largest player count"), std::string::npos) << text;
  status = std::system(
      (base + " --sweep-limit-ms 0.000001 > /dev/null 2>&1").c_str());  // no count can meet it
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
}

// A mistyped --log-level turned voxeld's logging off without a word.
TEST(CommandLine, VoxeldRefusesAnUnknownLogLevel) {
  const std::string cmd = std::string(VOXELD_PATH) + " --port 0 --log-level inf0 > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
}

// Every client of this test is 127.0.0.1: ServerProcess lifts the per-address caps; the
// players and squatters need room in the player and handshake caps too.
std::vector<std::string> generous_server_args() {
  return {"--max-clients", "2000", "--max-handshaking", "1000"};
}

// With --spread-addresses each player connects from its own loopback address, so a
// server with a per-address cap of one admits every player (the attack runs of
// docs/PERFORMANCE.md keep the caps and budgets at their defaults this way).
TEST(AttackLoadTest, SpreadAddressesMakeEachPlayerItsOwnAddress) {
  vox::test::ServerProcess server({"--max-per-address", "1", "--max-handshaking-per-address", "1"});
  const int players = 6;
  const TesterRun run =
      run_tester(server, "--players " + std::to_string(players) +
                             " --duration 2 --ramp 0.5 --view-radius 2 --spread-addresses");
  EXPECT_EQ(run.exit_code, 0);
  const std::string& text = run.json;
  for (const std::string& key :
       {"\"players_connected\":" + std::to_string(players), std::string("\"errors\":0")}) {
    EXPECT_NE(text.find(key), std::string::npos) << key << " in " << text;
  }
}

// Every kind of attacker for a few seconds beside a few players: the tester still exits 0
// (attackers' errors are not the players'), the players' figures stand apart and clean,
// and the report has the attackers and the server's RSS.
TEST(AttackLoadTest, PlayersBesideEveryKindOfAttackerExitZeroWithSeparateFigures) {
  vox::test::ServerProcess server(generous_server_args());
  const int players = kPlayers / 2;
  const TesterRun run =
      run_tester(server, "--players " + std::to_string(players) +
                             " --duration 4 --ramp 1 --edit-rate 1 --view-radius 3" +
                             " --attack flood:1,heavy:1,squat:1,slow:1,empty:1");
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_TRUE(server.running());
  const std::string& text = run.json;
  // The honest figures stay at the top level; the attackers' own "disconnects" are inside
  // "attackers", so the honest ones are matched with their neighbours.
  for (const std::string& key :
       {"\"players_connected\":" + std::to_string(players),
        std::string("\"decode_failures\":0,\"errors\":0,\"disconnects\":0,"),
        std::string("\"edit_to_delta_ms\""), std::string("\"refused_by_status\""),
        std::string("\"attackers\":{\"mix\":\"flood:1,heavy:1,squat:1,slow:1,empty:1\""),
        std::string("\"server_rss\":{\"pid\":")}) {
    EXPECT_NE(text.find(key), std::string::npos) << key << " in " << text;
  }
  // Every kind connected at least once and sent something.
  for (const char* kind : {"flood", "heavy", "squat", "slow", "empty"}) {
    std::smatch m;
    const std::regex re(
        std::string("\"") + kind +
        "\":\\{\"clients\":1,\"sockets\":\\d+,\"connects\":(\\d+),.*?\"messages_sent\":(\\d+)");
    ASSERT_TRUE(std::regex_search(text, m, re)) << kind << " in " << text;
    EXPECT_GT(std::stoul(m[1]), 0u) << kind;
    EXPECT_GT(std::stoul(m[2]), 0u) << kind;
  }
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex("\"heavy\":\\{.*?\"edits_sent\":(\\d+)")));
  EXPECT_GT(std::stoul(m[1]), 0u);
}

}  // namespace

// ---- --token-key: the players' signed tokens ---------------------------------------------

namespace {

// The key file as voxel-cli keygen writes it reads back, and the tokens minted with it
// verify with the public key, as players sim-0..sim-N-1 (distinct: one would replace another).
TEST(PlayerTokens, VerifyWithThePublicKeyAndNameDistinctPlayers) {
  namespace auth = vox::auth;
  const auth::KeyPair keys = auth::generate_key_pair();
  const vox::test::TempDir tmp("lt_key");
  const std::string path = (tmp / "key").string();
  std::ofstream(path) << auth::kPrivateKeyComment << auth::key_to_text(keys.seed) << "\n";
  const auth::SecretSeed seed = vox::auth::read_private_key_file(path);
  std::filesystem::remove(path);
  EXPECT_EQ(seed, keys.seed);
  EXPECT_THROW(vox::auth::read_private_key_file(path), std::runtime_error);

  const int64_t now = 1'800'000'000;
  const auto tokens = vox::loadtest::mint_player_tokens(seed, 3, now + 60);
  ASSERT_EQ(tokens.size(), 3u);
  std::set<std::string> ids;
  for (size_t i = 0; i < tokens.size(); ++i) {
    const auth::VerifiedToken v = auth::verify_token(tokens[i], keys.public_key, now);
    ASSERT_EQ(v.error, auth::TokenError::kNone) << v.message;
    EXPECT_EQ(v.claims->player_id, "sim-" + std::to_string(i));
    EXPECT_EQ(v.claims->display_name, "sim" + std::to_string(i));
    EXPECT_EQ(v.claims->role, auth::Role::kPlayer);
    ids.insert(v.claims->player_id);
  }
  EXPECT_EQ(ids.size(), tokens.size());
  const auth::KeyPair other = auth::generate_key_pair();
  EXPECT_EQ(auth::verify_token(tokens[0], other.public_key, now).error,
            auth::TokenError::kBadSignature);
}

}  // namespace
