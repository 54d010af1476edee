// Polling for a condition another thread or process makes true, in tests.
#pragma once

#include <chrono>
#include <thread>

namespace vox::test {

// Polls `done` every 10 ms for up to `limit`; true as soon as it holds.
template <typename F>
bool eventually(F done, std::chrono::milliseconds limit = std::chrono::seconds(10)) {
  for (auto end = std::chrono::steady_clock::now() + limit; std::chrono::steady_clock::now() < end;
       std::this_thread::sleep_for(std::chrono::milliseconds(10))) {
    if (done()) return true;
  }
  return done();
}

}  // namespace vox::test
