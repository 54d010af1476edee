// voxeld's flags (server/daemon/voxeld_flags.hpp): defaults, each rule refused with its own
// line naming the flag and the value, several bad flags each said, and values reaching the
// parts' configurations.
#include "server/daemon/voxeld_flags.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "server/auth/player_token.hpp"
#include "server/daemon/json_log.hpp"
#include "server/daemon/reload.hpp"

namespace vox::daemon {
namespace {

struct Parsed {
  int code;
  VoxeldConfig config;
  std::string out, err;
};

Parsed parse(std::vector<std::string> args) {
  Parsed p;
  std::ostringstream out, err;
  p.code = parse_voxeld_flags(args, p.config, out, err);
  p.out = out.str();
  p.err = err.str();
  return p;
}

size_t lines(const std::string& text) {
  return static_cast<size_t>(std::count(text.begin(), text.end(), '\n'));
}

TEST(VoxeldFlags, NoFlagsGiveTheDocumentedDefaults) {
  const Parsed p = parse({});
  ASSERT_EQ(p.code, -1) << p.err;
  EXPECT_EQ(p.err, "");
  EXPECT_EQ(p.config.net.port, 7777);
  EXPECT_EQ(p.config.net.bind, "127.0.0.1");
  EXPECT_EQ(p.config.net.max_clients, 256u);
  EXPECT_EQ(p.config.world_dir, "world");
  EXPECT_FALSE(p.config.seed.has_value());
  EXPECT_EQ(p.config.world.seed, 1u);
  EXPECT_FALSE(p.config.metrics_port.has_value());
  EXPECT_EQ(p.config.world.max_memory, default_max_memory());
  EXPECT_EQ(p.config.world.evict_after, std::chrono::seconds(120));
  EXPECT_EQ(p.config.world.checkpoint.interval, std::chrono::seconds(10));
  EXPECT_EQ(p.config.world.load_burst_per_address, 8000);
  EXPECT_EQ(p.config.net.open_role, auth::Role::kPlayer);
  EXPECT_FALSE(p.config.net.auth_key.has_value());
}

TEST(VoxeldFlags, HelpListsTheFlagsAndExitsZero) {
  const Parsed p = parse({"--help"});
  EXPECT_EQ(p.code, 0);
  EXPECT_NE(p.out.find("usage: voxeld"), std::string::npos);
  EXPECT_NE(p.out.find("--max-memory"), std::string::npos);
  EXPECT_NE(p.out.find("--lod-remesh-interval-ms"), std::string::npos);
}

TEST(VoxeldFlags, ValuesReachThePartsConfigurations) {
  const Parsed p = parse({"--port",
                          "0",
                          "--seed",
                          "42",
                          "--max-memory",
                          "512M",
                          "--evict-after",
                          "7",
                          "--checkpoint-interval",
                          "0.5",
                          "--idle-timeout-ms",
                          "1500",
                          "--lod-remesh-interval-ms",
                          "100",
                          "--load-budget-per-address",
                          "10",
                          "--metrics-port",
                          "0",
                          "--open-role",
                          "viewer",
                          "--io-threads",
                          "2"});
  ASSERT_EQ(p.code, -1) << p.err;
  EXPECT_EQ(p.config.net.port, 0);
  EXPECT_EQ(p.config.seed, 42u);
  EXPECT_EQ(p.config.world.seed, 42u);
  EXPECT_EQ(p.config.world.max_memory, size_t{512} << 20);
  EXPECT_EQ(p.config.world.evict_after, std::chrono::seconds(7));
  EXPECT_EQ(p.config.world.checkpoint.interval, std::chrono::milliseconds(500));
  EXPECT_EQ(p.config.net.idle_timeout, std::chrono::milliseconds(1500));
  EXPECT_EQ(p.config.world.lod.remesh_interval, std::chrono::milliseconds(100));
  EXPECT_EQ(p.config.world.load_burst_per_address, 80);
  EXPECT_EQ(p.config.metrics_port, 0);
  EXPECT_EQ(p.config.net.open_role, auth::Role::kViewer);
  EXPECT_EQ(p.config.io_threads, 2);
}

TEST(VoxeldFlags, EachBadFlagIsRefusedWithItsOwnLine) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--io-threads", "0"}, "--io-threads must be 1..64 (got 0)"},
      {{"--threads=-1"}, "--threads must be >= 0"},
      {{"--idle-timeout-ms", "0"}, "--idle-timeout-ms must be > 0"},
      {{"--handshake-timeout-ms=-5"}, "--handshake-timeout-ms must be > 0"},
      {{"--write-timeout-ms", "0"}, "--write-timeout-ms must be > 0"},
      {{"--frame-timeout-ms", "0"}, "--frame-timeout-ms must be > 0"},
      {{"--evict-after", "0"}, "--evict-after must be >= 1"},
      {{"--metrics-port", "70000"}, "--metrics-port must be 0..65535"},
      {{"--metrics-port=-1"}, "--metrics-port must be 0..65535"},
      {{"--checkpoint-interval", "0"}, "--checkpoint-interval must be 0.01..86400"},
      {{"--max-view-radius", "33"}, "--max-view-radius must be 0..32"},
      {{"--max-lod-level", "7"}, "--max-lod-level must be 0..6"},
      {{"--max-lod-distance", "0.5"}, "--max-lod-distance must be 1..4"},
      {{"--lod-remesh-interval-ms", "5"}, "--lod-remesh-interval-ms must be 10..750"},
      {{"--max-clients", "0"}, "--max-clients must be >= 1"},
      {{"--max-handshaking", "0"}, "--max-handshaking must be >= 1"},
      {{"--load-budget-per-address", "0.1"}, "--load-budget-per-address must be 0"},
      {{"--log-level", "verbose"}, "--log-level must be trace"},
      {{"--edit-burst", "10"}, "--edit-burst must be at least"},
      {{"--admin-edit-budget", "5", "--admin-edit-burst", "10"}, "--admin-edit-burst must be"},
      {{"--open-role", "god"}, "--open-role must be viewer, player or admin (got 'god')"},
      {{"--auth-public-key", "/nonexistent/game.pub"},
       "--auth-public-key /nonexistent/game.pub: cannot be read"},
      {{"--max-memory", "12Q"}, "--max-memory must be bytes"},
      {{"--max-memory=-1"}, "--max-memory must be bytes"},
      {{"--max-memory", "63M"}, "--max-memory must be bytes"},
      {{"--store", "mysql://x"}, "--store must be a postgresql:// URI"},
      {{"--http-trusted-proxy", "proxy.example"},
       "--http-trusted-proxy must be an IP address such as 127.0.0.1 (got 'proxy.example')"},
  };
  for (const auto& [args, message] : cases) {
    const Parsed p = parse(args);
    EXPECT_EQ(p.code, 2) << args[0];
    EXPECT_EQ(lines(p.err), 1u) << p.err;
    EXPECT_EQ(p.err.rfind("voxeld: " + message, 0), 0u) << "got: " << p.err;
  }
}

TEST(VoxeldFlags, SeveralBadFlagsAreEachSaid) {
  const Parsed p = parse({"--io-threads", "0", "--max-clients", "0", "--log-level", "loud"});
  EXPECT_EQ(p.code, 2);
  EXPECT_EQ(lines(p.err), 3u) << p.err;
  EXPECT_NE(p.err.find("--io-threads"), std::string::npos);
  EXPECT_NE(p.err.find("--max-clients"), std::string::npos);
  EXPECT_NE(p.err.find("--log-level"), std::string::npos);
}

TEST(VoxeldFlags, AnUnknownFlagOrAMalformedNumberIsBadUsage) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--no-such-flag"}, {"--port", "seventy"}, {"--port", "70000"}}) {
    const Parsed p = parse(args);
    EXPECT_EQ(p.code, 2) << args[0];
    EXPECT_EQ(p.err.rfind("voxeld: ", 0), 0u) << p.err;
    EXPECT_NE(p.err.find("(see --help)"), std::string::npos) << p.err;
  }
}

}  // namespace
}  // namespace vox::daemon

namespace vox::daemon {
namespace {

// A configuration file in a fresh temporary directory, removed with it.
struct ConfigFileOnDisk {
  std::string path;
  explicit ConfigFileOnDisk(const std::string& text) {
    char dir[] = "/tmp/voxeld_config_XXXXXX";
    path = std::string(::mkdtemp(dir)) + "/voxeld.conf";
    std::ofstream(path) << text;
  }
  ~ConfigFileOnDisk() {
    std::remove(path.c_str());
    std::remove(path.substr(0, path.rfind('/')).c_str());
  }
};

TEST(VoxeldConfigFile, EveryFlagCanBeSetThereAndAFlagGivenWithItWins) {
  const ConfigFileOnDisk file(
      "# a studio's server\n"
      "port = 7800   # the game port\n"
      "max-clients = 900\n"
      "\n"
      "max-memory = 2G\n"
      "in-memory = true\n"
      "http-allow-origin = https://a.example\n"
      "http-allow-origin = https://b.example\n"
      "log-level = warn\n");
  const Parsed p = parse({"--config", file.path, "--max-clients", "50"});
  ASSERT_EQ(p.code, -1) << p.err;
  EXPECT_EQ(p.config.net.port, 7800);
  EXPECT_EQ(p.config.net.max_clients, 50u) << "the command line wins";
  EXPECT_EQ(p.config.world.max_memory, size_t{2} << 30);
  EXPECT_TRUE(p.config.in_memory);
  EXPECT_EQ(p.config.log_level, "warn");
  ASSERT_TRUE(p.config.net.http.has_value());
  EXPECT_EQ(p.config.net.http->allow_origins,
            (std::vector<std::string>{"https://a.example", "https://b.example"}));
}

TEST(VoxeldConfigFile, EachBadLineIsOneErrorNamingTheFileTheLineAndTheKey) {
  const ConfigFileOnDisk file(
      "port = 7800\n"
      "max-clientz = 10\n"
      "max-clients = many\n"
      "[server]\n"
      "just words\n"
      "port = 7801\n"
      "config = /etc/other.conf\n");
  const Parsed p = parse({"--config", file.path});
  EXPECT_EQ(p.code, 2);
  EXPECT_EQ(lines(p.err), 6u) << p.err;
  EXPECT_NE(p.err.find(file.path + ":2: key 'max-clientz': not an option"), std::string::npos)
      << p.err;
  EXPECT_NE(p.err.find(file.path + ":3: key 'max-clients':"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find(file.path + ":4: sections are not used"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find(file.path + ":5: expected key = value"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find(file.path + ":6: key 'port': set on line 1 already"), std::string::npos)
      << p.err;
  EXPECT_NE(p.err.find(file.path + ":7: key 'config': not allowed"), std::string::npos) << p.err;
}

TEST(VoxeldConfigFile, AValueBreakingItsRuleNamesWhereTheFileSetIt) {
  const ConfigFileOnDisk file("io-threads = 1\nmax-view-radius = 99\n");
  const Parsed p = parse({"--config", file.path});
  EXPECT_EQ(p.code, 2);
  EXPECT_NE(p.err.find("--max-view-radius must be 0..32 (got 99) (" + file.path + ":2)"),
            std::string::npos)
      << p.err;
  const Parsed flag = parse({"--config", file.path, "--max-view-radius", "40"});
  EXPECT_EQ(flag.err.find(file.path), std::string::npos) << "the flag broke it: " << flag.err;
}

// Review findings: a '#' inside a value cut it short (voxeld then served another, empty
// world), a list from the file joined the command line's instead of giving way to it, an
// empty switch read as true, and a printed default read back as explicitly set.
TEST(VoxeldConfigFile, ValuesKeepTheirHashesQuotesAndSpacesAndTheCommandLineReplacesAList) {
  const ConfigFileOnDisk file(
      "\xef\xbb\xbf# saved by Notepad, with a byte order mark\r\n"
      "world = /srv/worlds/#1   # the first\r\n"
      "http-root = \" /srv/web with spaces \"  # quoted\n"
      "http-trusted-proxy = 10.0.0.5\n");
  const Parsed p = parse({"--config", file.path, "--http-trusted-proxy", "10.0.0.9"});
  ASSERT_EQ(p.code, -1) << p.err;
  EXPECT_EQ(p.config.world_dir, "/srv/worlds/#1");
  ASSERT_TRUE(p.config.net.http.has_value());
  EXPECT_EQ(p.config.net.http->root, " /srv/web with spaces ");
  EXPECT_EQ(p.config.net.http->trusted_proxies, (std::vector<std::string>{"10.0.0.9"}));
  EXPECT_FALSE(p.config.net.http_port_required);

  const Parsed printed = parse({"--config", file.path, "--print-config"});
  ASSERT_EQ(printed.code, 0) << printed.err;
  EXPECT_NE(printed.out.find("\nworld = \"/srv/worlds/#1\"\n"), std::string::npos) << printed.out;
  EXPECT_NE(printed.out.find("\nhttp-root = \" /srv/web with spaces \"\n"), std::string::npos);
  EXPECT_NE(printed.out.find("\n# http-port = 7780\n"), std::string::npos) << "a default stays one";
  const ConfigFileOnDisk again(printed.out);
  const Parsed read = parse({"--config", again.path});
  ASSERT_EQ(read.code, -1) << read.err;
  EXPECT_EQ(read.config.world_dir, "/srv/worlds/#1");
  EXPECT_FALSE(read.config.net.http_port_required)
      << "7780 busy must still only leave the viewer off";

  const ConfigFileOnDisk empty("in-memory =\nport = \"7800\n");
  const Parsed bad = parse({"--config", empty.path});
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find(":1: key 'in-memory': no value"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find(":2: key 'port': a quoted value without its closing"), std::string::npos)
      << bad.err;
}

TEST(VoxeldConfigFile, AFileThatIsNoConfigurationIsRefusedWithoutReadingItAll) {
  EXPECT_EQ(parse({"--config", "/dev/zero"}).code, 2);
  std::string junk;
  for (int i = 0; i < 1000; ++i) junk += "junk line " + std::to_string(i) + "\n";
  const ConfigFileOnDisk file(junk);
  const Parsed p = parse({"--config", file.path});
  EXPECT_EQ(p.code, 2);
  EXPECT_LE(lines(p.err), 21u) << "at most 20 errors and a count";
}

TEST(VoxeldConfigFile, AMissingFileIsOneError) {
  const Parsed p = parse({"--config", "/nonexistent/voxeld.conf"});
  EXPECT_EQ(p.code, 2);
  EXPECT_EQ(p.err, "voxeld: /nonexistent/voxeld.conf: cannot be read\n");
}

TEST(VoxeldConfigFile, PrintConfigWritesAFileThatReadsBackToTheSameConfiguration) {
  const Parsed printed =
      parse({"--print-config", "--port", "7900", "--max-memory", "3G", "--http-allow-origin",
             "https://a.example", "--keep-log", "--max-lod-distance", "1.5"});
  ASSERT_EQ(printed.code, 0) << printed.err;
  EXPECT_NE(printed.out.find("\nport = 7900\n"), std::string::npos) << printed.out;
  EXPECT_NE(printed.out.find("\n# seed =\n"), std::string::npos) << "no value: commented";
  EXPECT_EQ(printed.out.find("print-config ="), std::string::npos);
  const ConfigFileOnDisk file(printed.out);
  const Parsed read = parse({"--config", file.path});
  ASSERT_EQ(read.code, -1) << read.err;
  EXPECT_EQ(read.config.net.port, 7900);
  EXPECT_EQ(read.config.world.max_memory, size_t{3} << 30);
  EXPECT_TRUE(read.config.world.history.keep_all);
  EXPECT_FLOAT_EQ(read.config.net.max_lod_distance, 1.5f);
  const Parsed again = parse({"--config", file.path, "--print-config"});
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_EQ(again.out, printed.out) << "a fixed point";
}

}  // namespace
}  // namespace vox::daemon

namespace vox::daemon {
namespace {

std::string escaped(std::string_view text) {
  std::string out;
  append_json_escaped(text, out);
  return out;
}

// --log-format json: a client's name or a damaged string in a message must not break the
// line's JSON (a log shipper drops or misreads a line that is not).
TEST(JsonLog, AMessageIsEscapedIntoOneValidJsonString) {
  EXPECT_EQ(escaped("player 'a\"b' said \\ hi"), "player 'a\\\"b' said \\\\ hi");
  EXPECT_EQ(escaped("two\nlines\tand \x01 \x7f"), "two\\nlines\\tand \\u0001 \\u007f");
  EXPECT_EQ(escaped("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"),
            "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
  // A lone continuation byte, a truncated sequence, an overlong '/', a surrogate.
  EXPECT_EQ(escaped("\x80 \xe2\x82 \xc0\xaf \xed\xa0\x80"),
            "\\ufffd \\ufffd\\ufffd \\ufffd\\ufffd \\ufffd\\ufffd\\ufffd");
}

TEST(JsonLog, LogFormatIsTextOrJson) {
  EXPECT_FALSE(parse({}).config.json_logs);
  EXPECT_TRUE(parse({"--log-format", "json"}).config.json_logs);
  const Parsed bad = parse({"--log-format", "xml"});
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--log-format must be text or json (got 'xml')"), std::string::npos);
}

}  // namespace
}  // namespace vox::daemon

namespace vox::daemon {
namespace {

TEST(Reload, ItAppliesBudgetsCapsLogLevelAndKeyAndNamesWhatNeedsARestart) {
  const Parsed now = parse({"--edit-budget", "1000", "--port", "7000"});
  ASSERT_EQ(now.code, -1) << now.err;
  const Parsed next = parse(
      {"--edit-budget", "2000", "--port", "7001", "--max-clients", "9", "--log-level", "debug"});
  ASSERT_EQ(next.code, -1) << next.err;
  const ReloadPlan plan = plan_reload(now.config, next.config);
  EXPECT_EQ(plan.changed,
            (std::vector<std::string>{"edit-budget: 1000 -> 2000", "log-level: info -> debug",
                                      "max-clients: 256 -> 9"}));
  EXPECT_EQ(plan.kept, std::vector<std::string>{"port: 7000 -> 7001 needs a restart (still 7000)"});
  EXPECT_EQ(plan.after.net.edit_budget_rate, 2000);
  EXPECT_EQ(plan.after.net.max_clients, 9u);
  EXPECT_EQ(plan.after.net.port, 7000);  // kept
  EXPECT_EQ(plan.after.log_level, "debug");
  // Applied again, the plan is empty but for what still needs a restart.
  const ReloadPlan again = plan_reload(plan.after, next.config);
  EXPECT_TRUE(again.changed.empty());
  EXPECT_EQ(again.kept.size(), 1u);
}

TEST(Reload, ANewKeyInTheSameFileIsANewKeyButAnOpenServerStaysOpen) {
  const ConfigFileOnDisk file("");  // its directory and name; it holds a key here
  const std::string& path = file.path;
  const auto write_key = [&](const auth::PublicKey& k) {
    std::ofstream(path) << auth::key_to_text(k) << "\n";
  };
  write_key(auth::generate_key_pair().public_key);
  const Parsed a = parse({"--auth-public-key", path});
  write_key(auth::generate_key_pair().public_key);
  const Parsed b = parse({"--auth-public-key", path});
  ASSERT_EQ(a.code, -1) << a.err;
  ASSERT_EQ(b.code, -1) << b.err;
  const ReloadPlan rotated = plan_reload(a.config, b.config);
  ASSERT_EQ(rotated.changed.size(), 1u);
  EXPECT_NE(rotated.changed[0].find("(a new key)"), std::string::npos) << rotated.changed[0];
  EXPECT_EQ(rotated.after.net.auth_key, b.config.net.auth_key);
  const ReloadPlan opened = plan_reload(parse({}).config, b.config);
  ASSERT_EQ(opened.kept.size(), 1u);
  EXPECT_NE(opened.kept[0].find("between an open server and player tokens"), std::string::npos);
  EXPECT_FALSE(opened.after.net.auth_key);
}

}  // namespace
}  // namespace vox::daemon
