// One request to a server and its answer, for voxel-cli's admin commands (region, players,
// kick, ban, ...): a fresh connection, Hello with the token of --token or VOXEL_TOKEN.
#pragma once

#include <functional>

#include "client-cli/cli_options.hpp"
#include "client/voxel_client.hpp"

namespace vox::cli {

// Sends `request` and returns the first message `is_answer` accepts. Throws
// std::runtime_error on a server Error, or when no answer (`what`) comes within 10 s.
wire::Envelope server_request(const po::variables_map& vm, const wire::Envelope& request,
                              const std::function<bool(const wire::Envelope&)>& is_answer,
                              const char* what);

}  // namespace vox::cli
