// A cluster node's configuration file (docs/CLUSTER.md): where the cluster's PostgreSQL
// and NATS are and the credentials for both — kept in a file readable by voxeld's user
// only, never on a command line — plus the world's name, this node's id, the lease and
// the zones' size. `key = value` lines, `#` comments (Boost.program_options' config-file
// syntax):
//
//   database = postgresql://voxeld:secret@10.0.0.5/voxworld
//   nats = nats://10.0.0.6:4222
//   nats_user = voxeld
//   nats_password = secret
//   world = main            # subjects' prefix: letters, digits, '-' and '_'
//   node = eu-1             # default: <host name>-<process id>, new for every run
//   lease_ms = 3000
//   zone_chunks = 16        # fixed when the world is made; every node must agree
//   max_followed_zones = 32 # zones followed at once for players' views (each holds a
//                           # database connection: max_connections >= nodes x (this + 5))
//   follow_idle_s = 300     # a zone no player here viewed this long is no longer followed,
//                           # and its changed chunks leave memory (installed again when viewed)
//
// Pure functions: any thread.
#pragma once

#include <chrono>
#include <string>

#include "server/cluster/nats_link.hpp"

namespace vox::cluster {

struct ClusterConfig {
  std::string database;  // a postgresql:// URI
  NatsConfig nats;
  std::string world = "main";
  std::string node;
  std::chrono::milliseconds lease{3000};
  int zone_chunks = 16;
  int max_followed_zones = 32;
  std::chrono::seconds follow_idle{300};
};

// Throws ClusterError naming the file (and the key) for a file that cannot be read, an
// unknown key, a bad value or a missing `database` or `nats`. A file others may read is
// accepted with a warning (it holds passwords).
ClusterConfig read_cluster_config(const std::string& path);

}  // namespace vox::cluster
