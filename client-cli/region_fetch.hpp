// Fetching the chunk meshes around a point: the shared first half of export and slice.
#pragma once

#include <array>
#include <chrono>
#include <memory>
#include <string>

#include "client-cli/cli_options.hpp"
#include "client/voxel_client.hpp"

namespace vox::cli {

// Connects to `server`, asks for the view of `radius` chunks around `at` (with
// `lod_level` > 0, levels 0 .. lod_level, docs/PROTOCOL.md 4.10) and receives until the
// server says the view is complete (ViewReady), or `timeout` (terrain is generated on
// demand). The returned client holds the chunks. Throws std::invalid_argument for a bad
// server string, std::runtime_error for anything else.
std::unique_ptr<client::Client> fetch_region(const ServerAccess& server, const std::string& name,
                                             const std::array<float, 3>& at, uint32_t radius,
                                             std::chrono::milliseconds timeout,
                                             uint32_t lod_level = 0, float lod_distance = 0);

}  // namespace vox::cli
