#include "server/cluster/cluster_config.hpp"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <boost/program_options.hpp>
#include <fstream>

#include "server/cluster/zone_wire.hpp"
#include "server/store/world_store.hpp"
#include "server/world/zone.hpp"

namespace vox::cluster {

namespace po = boost::program_options;

namespace {

std::string default_node() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0 || host[0] == 0)
    std::snprintf(host, sizeof host, "node");
  return std::string(host) + "-" + std::to_string(getpid());
}

}  // namespace

ClusterConfig read_cluster_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ClusterError("cluster configuration " + path + ": cannot be read");
  ClusterConfig c;
  int64_t lease_ms = 3000, follow_idle_s = 300;
  po::options_description keys;
  keys.add_options()("database", po::value(&c.database))("nats", po::value(&c.nats.url))(
      "nats_user", po::value(&c.nats.user))("nats_password", po::value(&c.nats.password))(
      "world", po::value(&c.world))("node", po::value(&c.node))("lease_ms", po::value(&lease_ms))(
      "zone_chunks", po::value(&c.zone_chunks))(
      "max_followed_zones", po::value(&c.max_followed_zones))("follow_idle_s",
                                                              po::value(&follow_idle_s));
  try {
    po::variables_map vm;
    po::store(po::parse_config_file(in, keys, false), vm);
    po::notify(vm);
  } catch (const po::error& e) {
    throw ClusterError("cluster configuration " + path + ": " + e.what());
  }
  const auto bad = [&path](const std::string& why) {
    return ClusterError("cluster configuration " + path + ": " + why);
  };
  if (c.database.empty() || !store::is_postgres_uri(c.database))
    throw bad("database must be a postgresql:// URI");
  if (c.nats.url.empty()) throw bad("nats must name the NATS server (nats://host:port)");
  if (!valid_world_name(c.world)) throw bad("world: letters, digits, '-' and '_' (1 to 64)");
  if (lease_ms < 300 || lease_ms > 600000) throw bad("lease_ms must be 300 .. 600000");
  c.lease = std::chrono::milliseconds(lease_ms);
  if (c.zone_chunks < 1 || c.zone_chunks > world::kMaxZoneChunks)
    throw bad("zone_chunks must be 1 .. " + std::to_string(world::kMaxZoneChunks));
  if (c.max_followed_zones < 1 || c.max_followed_zones > 1024)
    throw bad("max_followed_zones must be 1 .. 1024");
  if (follow_idle_s < 1 || follow_idle_s > 86400) throw bad("follow_idle_s must be 1 .. 86400");
  c.follow_idle = std::chrono::seconds(follow_idle_s);
  if (c.node.empty()) c.node = default_node();
  if (c.node.size() > 200) throw bad("node: at most 200 bytes");
  c.nats.name = "voxeld " + c.node;
  struct stat st {};
  if (stat(path.c_str(), &st) == 0 && (st.st_mode & (S_IRGRP | S_IROTH)) != 0)
    spdlog::warn(
        "cluster configuration {}: others may read it, and it holds passwords "
        "(chmod 600)",
        path);
  return c;
}

}  // namespace vox::cluster
