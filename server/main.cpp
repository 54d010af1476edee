// voxeld: its flags into configurations, then the server (server/daemon).
#include <iostream>
#include <string>
#include <vector>

#include "server/daemon/voxeld.hpp"

int main(int argc, char** argv) {
#ifdef VOXEL_JEMALLOC
  constexpr const char* kAllocator = "jemalloc";
#else
  constexpr const char* kAllocator = "the system allocator";
#endif
  vox::daemon::VoxeldConfig config;
  const int code = vox::daemon::parse_voxeld_flags(std::vector<std::string>(argv + 1, argv + argc),
                                                   config, std::cout, std::cerr);
  if (code >= 0) return code;
  return vox::daemon::run_voxeld(std::move(config), kAllocator);
}
