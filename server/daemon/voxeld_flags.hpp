// voxeld's command line: every flag, its default and its help in one table (voxeld_flags.cpp),
// parsed, then checked one rule per flag, into the configurations of the parts it sets.
// The table is program_options', so a config file can be read with the same table
// (po::parse_config_file). Pure but for reading --auth-public-key's file; any thread.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "server/net/server_config.hpp"
#include "server/pipeline/world_pipeline.hpp"

namespace vox::daemon {

struct VoxeldConfig {
  net::ServerConfig net;
  pipeline::PipelineConfig world;  // its store pointers are set once the store is open
  std::optional<uint64_t> seed;    // --seed, when given (an existing world must have it)
  std::string world_dir = "world";
  std::string store_uri;  // postgresql://... instead of world_dir
  bool in_memory = false;
  std::string cluster_file;  // --cluster: a node of a cluster world (docs/CLUSTER.md)
  std::string port_file, metrics_port_file, http_port_file;
  std::optional<uint16_t> metrics_port;
  int io_threads = 1;
  int stats_seconds = 10;
  std::string log_level = "info";
  bool json_logs = false;  // --log-format json (json_log.hpp)
  // What a reload (SIGHUP) parses again, and compares: the arguments as given, and every
  // flag's effective value as text (voxeld --print-config's), by name.
  std::vector<std::string> args;
  std::map<std::string, std::vector<std::string>> effective;
};

// Parses voxeld's arguments (argv[1..]) into `config`. Returns -1 to go on, else the exit
// code: 0 after --help (written to out), 2 for bad usage: one line on err for each flag
// that breaks its rule, each naming the flag, its range and the value given.
int parse_voxeld_flags(const std::vector<std::string>& args, VoxeldConfig& config,
                       std::ostream& out, std::ostream& err);

// Half the machine's memory, at most 4 GiB: a dedicated server's share (--max-memory's
// default).
size_t default_max_memory();

}  // namespace vox::daemon
