// The filters `world history` and `rollback` share: a player, a box, a time span; parsed
// from --player, --min/--max, --since/--until (cli_options.hpp's forms).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "client-cli/cli_options.hpp"
#include "server/world/edit.hpp"

namespace vox::cli {

struct EditFilter {
  std::optional<std::string> player;  // "-": edits without an author (an open server)
  std::optional<world::VoxelBox> box;
  int64_t since_ms = std::numeric_limits<int64_t>::min();
  int64_t until_ms = std::numeric_limits<int64_t>::max();  // inclusive
};

void add_edit_filter_options(po::options_description& opts, const char* command);
// std::invalid_argument naming `command` and the flag when one is wrong.
EditFilter parse_edit_filter(const po::variables_map& vm, const char* command);

}  // namespace vox::cli
