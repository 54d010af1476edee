// A cluster node's configuration file (server/cluster/cluster_config.hpp): what it sets,
// and the one-line errors for a file that is missing, has a key the node does not know or
// a value out of range.
#include "server/cluster/cluster_config.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/temp_dir.hpp"

namespace vox::cluster {
namespace {

std::string write(const test::TempDir& tmp, const std::string& name, const std::string& text) {
  const std::string path = (tmp / name).string();
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  try {
    read_cluster_config(path);
  } catch (const ClusterError& e) {
    return e.what();
  }
  return "";
}

constexpr const char* kGood =
    "# a node\n"
    "database = postgresql://voxeld:pg-secret@10.0.0.5/voxworld\n"
    "nats = nats://10.0.0.6:4222\n"
    "nats_user = voxeld\n"
    "nats_password = nats-secret\n"
    "world = main\n"
    "node = eu-1\n"
    "lease_ms = 2000\n"
    "zone_chunks = 8\n"
    "max_followed_zones = 12\n"
    "follow_idle_s = 30\n";

TEST(ClusterConfig, AFileSetsEveryKey) {
  const test::TempDir tmp("cluster_config");
  const ClusterConfig c = read_cluster_config(write(tmp, "good.conf", kGood));
  EXPECT_EQ(c.database, "postgresql://voxeld:pg-secret@10.0.0.5/voxworld");
  EXPECT_EQ(c.nats.url, "nats://10.0.0.6:4222");
  EXPECT_EQ(c.nats.user, "voxeld");
  EXPECT_EQ(c.nats.password, "nats-secret");
  EXPECT_EQ(c.world, "main");
  EXPECT_EQ(c.node, "eu-1");
  EXPECT_EQ(c.lease.count(), 2000);
  EXPECT_EQ(c.zone_chunks, 8);
  EXPECT_EQ(c.max_followed_zones, 12);
  EXPECT_EQ(c.follow_idle.count(), 30);
  // Without a node id, each run gets its own (a restart fences the run before it).
  const ClusterConfig d = read_cluster_config(
      write(tmp, "min.conf", "database = postgresql:///w\nnats = nats://127.0.0.1:4222\n"));
  EXPECT_FALSE(d.node.empty());
  EXPECT_EQ(d.zone_chunks, 16);
  EXPECT_EQ(d.lease.count(), 3000);
  EXPECT_EQ(d.follow_idle.count(), 300);
}

TEST(ClusterConfig, BadFilesAreOneLineNamingTheFileAndTheKeyNeverAPassword) {
  const test::TempDir tmp("cluster_config");
  EXPECT_NE(error_of((tmp / "missing.conf").string()).find("missing.conf"), std::string::npos);
  const std::string unknown =
      error_of(write(tmp, "unknown.conf", std::string(kGood) + "nats_pasword = x\n"));
  EXPECT_NE(unknown.find("unknown.conf"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("nats_pasword"), std::string::npos) << unknown;
  const std::string lease =
      error_of(write(tmp, "lease.conf", std::string(kGood) + "lease_ms = 5\n"));
  EXPECT_NE(lease.find("lease_ms"), std::string::npos) << lease;
  EXPECT_NE(error_of(write(tmp, "nodb.conf", "nats = nats://h:1\n")).find("database"),
            std::string::npos);
  EXPECT_NE(error_of(write(tmp, "zones.conf", std::string(kGood) + "zone_chunks = 0\n"))
                .find("zone_chunks"),
            std::string::npos);
  EXPECT_NE(error_of(write(tmp, "idle.conf", std::string(kGood) + "follow_idle_s = 0\n"))
                .find("follow_idle_s"),
            std::string::npos);
  EXPECT_NE(error_of(write(tmp, "world.conf", std::string(kGood) + "world = a.b\n")).find("world"),
            std::string::npos);
  for (const std::string& e : {unknown, lease}) {
    EXPECT_EQ(e.find("secret"), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  }
}

}  // namespace
}  // namespace vox::cluster
