#include "client-cli/cli_options.hpp"

#include <cmath>
#include <cstdlib>
#include <ostream>
#include <stdexcept>
#include <tuple>

namespace vox::cli {

int parse_options(const std::vector<std::string>& args, const po::options_description& opts,
                  const po::positional_options_description* positional, const char* synopsis,
                  po::variables_map& vm, std::ostream& out, std::ostream& err) {
  return options::parse_args("voxel-cli", args, opts, positional, synopsis, vm, out, err);
}

po::options_description network_options(const std::string& command) {
  po::options_description opts("voxel-cli " + command + " options");
  opts.add_options()("help,h", "show this help")(
      "server", po::value<std::string>()->default_value(kDefaultServer), "HOST:PORT of voxeld")(
      "token", po::value<std::string>(),
      "a player token (voxel-cli token), for a server that checks them; default: $VOXEL_TOKEN");
  return opts;
}

ServerAccess server_access(const po::variables_map& vm) {
  ServerAccess a;
  std::tie(a.host, a.port) = parse_server(vm["server"].as<std::string>());
  if (vm.count("token")) {
    a.token = vm["token"].as<std::string>();
  } else if (const char* env = std::getenv("VOXEL_TOKEN")) {
    a.token = env;
  }
  return a;
}

void add_view_options(po::options_description& opts, const char* at_help, bool timeout) {
  opts.add_options()("at", po::value<std::string>()->required(), at_help)(
      "radius", po::value<uint32_t>()->default_value(2), "view radius in chunks");
  if (timeout) {
    opts.add_options()("timeout", po::value<double>()->default_value(120),
                       "seconds to wait for the whole view");
  }
}

std::array<int32_t, 3> parse_corner(const std::string& text, const char* what) {
  const std::array<float, 3> f = parse_vec3(text, what);
  std::array<int32_t, 3> out{};
  for (int a = 0; a < 3; ++a) {
    if (f[a] != std::floor(f[a]) || std::fabs(f[a]) > 1e9f)
      throw std::invalid_argument(std::string(what) + " must be whole sample coordinates");
    out[a] = static_cast<int32_t>(f[a]);
  }
  return out;
}

}  // namespace vox::cli
