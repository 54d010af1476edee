// Option parsing shared by voxel-cli's commands (the values themselves: options/).
#pragma once

#include <array>
#include <boost/program_options.hpp>
#include <chrono>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "options/option_values.hpp"

namespace vox::cli {

namespace po = boost::program_options;

// Parses args into vm. Returns -1 to go on, else the exit code to return (0 after
// --help, 2 for bad usage with a one-line message on err).
int parse_options(const std::vector<std::string>& args, const po::options_description& opts,
                  const po::positional_options_description* positional, const char* synopsis,
                  po::variables_map& vm, std::ostream& out, std::ostream& err);

using options::parse_server;
using options::parse_vec2;
using options::parse_vec3;
using options::timeout_of;

// "X,Y,Z" of whole sample coordinates; std::invalid_argument naming `what` otherwise.
std::array<int32_t, 3> parse_corner(const std::string& text, const char* what);

inline constexpr const char* kDefaultServer = "127.0.0.1:7777";

// The options of a network command: --help, --server and --token, under "voxel-cli NAME
// options".
po::options_description network_options(const std::string& command);

// Where a network command connects, and as whom: --server, and --token or else the
// environment variable VOXEL_TOKEN (a player token; empty: none). Throws
// std::invalid_argument for a bad --server.
struct ServerAccess {
  std::string host;
  uint16_t port = 0;
  std::string token;
};
ServerAccess server_access(const po::variables_map& vm);
// The options of a command that fetches a view: --at (meaning `at_help`), --radius in
// chunks (default 2) and, with `timeout`, --timeout (seconds to wait for the whole view).
void add_view_options(po::options_description& opts, const char* at_help, bool timeout);

// Runs a command's body and maps what it throws to the exit codes every command shares:
// std::invalid_argument (a bad option value) is 2, anything else 1, each as one line.
template <class Body>
int guarded(std::ostream& err, Body&& body) {
  try {
    return body();
  } catch (const std::invalid_argument& e) {
    err << "voxel-cli: " << e.what() << " (see --help)\n";
    return 2;
  } catch (const std::exception& e) {
    err << "voxel-cli: error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace vox::cli
