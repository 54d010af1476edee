// Runs an io_context on this thread until `done()` or 10 s (tests of one connection with
// no session around it).
#pragma once

#include <chrono>

#include "server/net/asio.hpp"

namespace vox::test {

template <class Done>
void run_io_until(boost::asio::io_context& io, Done&& done) {
  using namespace std::chrono_literals;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    io.restart();
    io.run_for(5ms);
  }
}

}  // namespace vox::test
