// The Server's lifetime against its sessions'. voxeld's main destroys the Server before
// the io_context, whose queued handlers still hold sessions: a session may outlive the
// Server and must not touch it (under AddressSanitizer a use would be a heap-use-after-free).
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <thread>

#include "client/voxel_client.hpp"
#include "server/net/server.hpp"

namespace vox::net {
namespace {

using namespace std::chrono_literals;

TEST(ServerLifetime, ASessionLeftQueuedWhenTheServerIsDestroyedServesWithoutTouchingIt) {
  pipeline::WorldPipeline pipeline(pipeline::PipelineConfig{.seed = 1, .threads = 1});
  ServerCounters counters;
  asio::io_context io;
  auto work = asio::make_work_guard(io);
  ServerConfig config;
  config.bind = "127.0.0.1";
  config.port = 0;
  auto server = std::make_unique<Server>(io, config, pipeline, counters);
  server->start();
  std::thread runner([&io] { io.run(); });

  auto c = std::make_unique<client::Client>();
  c->connect("127.0.0.1", server->port(), 5s);
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (server->session_count() == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  ASSERT_EQ(server->session_count(), 1u);

  // The Server goes while its session waits for Hello in the io_context.
  io.stop();
  runner.join();
  server.reset();
  io.restart();
  runner = std::thread([&io] { io.run(); });

  // The session handles Hello: its configuration (limits, version) is its own copy.
  const wire::Welcome welcome = c->handshake("alice", 10s);
  EXPECT_EQ(welcome.server_version(), config.server_version);
  EXPECT_EQ(welcome.max_view_radius(), config.max_view_radius);
  c.reset();
  work.reset();
  io.stop();
  runner.join();
}

}  // namespace
}  // namespace vox::net
