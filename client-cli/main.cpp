// voxel-cli: thin entry point; the commands live in the voxel_cli library.
#include <iostream>

#include "client-cli/commands.hpp"

int main(int argc, char** argv) {
  return vox::cli::run_cli(std::vector<std::string>(argv + 1, argv + argc), std::cout, std::cerr);
}
