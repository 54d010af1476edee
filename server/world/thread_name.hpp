// Names the calling thread (as `top -H`, `perf` and gdb show it): at most 15 characters,
// longer ones are cut. Any thread, at its start.
#pragma once

#include <pthread.h>

#include <string>

namespace vox {

inline void name_this_thread(const char* name) {
  const std::string cut = std::string(name).substr(0, 15);
  pthread_setname_np(pthread_self(), cut.c_str());
}

}  // namespace vox
