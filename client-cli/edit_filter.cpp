#include "client-cli/edit_filter.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace vox::cli {

void add_edit_filter_options(po::options_description& opts, const char* command) {
  const std::string c = command;
  opts.add_options()("player", po::value<std::string>(),
                     (c + ": this player id's edits ('-': no author)").c_str())(
      "min", po::value<std::string>(), (c + ": X,Y,Z, the box's lowest sample").c_str())(
      "max", po::value<std::string>(),
      (c + ": X,Y,Z, the box's highest sample: edits touching the box").c_str())(
      "until", po::value<std::string>(),
      (c + ": edits accepted up to this time (as --since)").c_str());
}

EditFilter parse_edit_filter(const po::variables_map& vm, const char* command) {
  const std::string c = command;
  EditFilter f;
  const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  if (vm.count("since"))
    f.since_ms = options::parse_time_ms(vm["since"].as<std::string>(), "--since", now);
  if (vm.count("until"))
    f.until_ms = options::parse_time_ms(vm["until"].as<std::string>(), "--until", now);
  if (vm.count("player")) f.player = vm["player"].as<std::string>();
  if (vm.count("min") != vm.count("max"))
    throw std::invalid_argument(c + ": --min and --max name a box together");
  if (vm.count("min")) {
    const auto lo = parse_vec3(vm["min"].as<std::string>(), "--min");
    const auto hi = parse_vec3(vm["max"].as<std::string>(), "--max");
    world::VoxelBox b;
    for (int a = 0; a < 3; ++a) {
      if (std::fabs(lo[a]) > 1e9f || std::fabs(hi[a]) > 1e9f || lo[a] > hi[a])
        throw std::invalid_argument(c + ": --min must be at most --max on every axis");
      b.lo[a] = static_cast<int32_t>(std::floor(lo[a]));
      b.hi[a] = static_cast<int32_t>(std::ceil(hi[a]));
    }
    f.box = b;
  }
  return f;
}

}  // namespace vox::cli
