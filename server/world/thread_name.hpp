// Names a thread (as `top -H`, `perf` and gdb show it): at most 15 characters, longer ones
// are cut. name_this_thread: any thread, at its start; named_thread starts one so named.
#pragma once

#include <pthread.h>

#include <string>
#include <thread>
#include <utility>

namespace vox {

inline void name_this_thread(const char* name) {
  const std::string cut = std::string(name).substr(0, 15);
  pthread_setname_np(pthread_self(), cut.c_str());
}

// A std::thread that names itself `name`, then runs `body`.
template <class Body>
std::thread named_thread(const char* name, Body body) {
  return std::thread([name, body = std::move(body)]() mutable {
    name_this_thread(name);
    body();
  });
}

}  // namespace vox
