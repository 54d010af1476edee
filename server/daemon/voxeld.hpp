// voxeld as a whole: opens the world store (refusing a bad one before anything listens),
// starts the pipeline, the TCP server and the metrics endpoint, and runs until SIGINT or
// SIGTERM, then stops them in order. The calling thread runs the first network thread.
#pragma once

#include "server/daemon/voxeld_flags.hpp"

namespace vox::daemon {

// Returns the process's exit code: 0 after a clean stop, 1 when the world cannot be opened
// or the server fails. `allocator` names the allocator in the start line.
int run_voxeld(VoxeldConfig config, const char* allocator);

}  // namespace vox::daemon
