// What the tests against a real voxeld share: clients that connect and say Hello, waits
// with deadlines (stretched in sanitizer builds) and terrain heights.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/voxel_client.hpp"
#include "server/world/terrain_generator.hpp"
#include "tests/server_process.hpp"

namespace vox::test {

using namespace std::chrono_literals;

// Sanitizer builds run the server several times slower: deadlines stretch, never shrink.
#ifdef VOXEL_SANITIZED
inline constexpr int kSlow = 6;
#else
inline constexpr int kSlow = 1;
#endif

inline std::unique_ptr<client::Client> connect_to(const ServerProcess& server) {
  auto c = std::make_unique<client::Client>();
  c->connect("127.0.0.1", server.port(), 5s);
  return c;
}

inline std::unique_ptr<client::Client> player(const ServerProcess& server,
                                              const std::string& name) {
  auto c = connect_to(server);
  c->handshake(name, 5s * kSlow);
  return c;
}

// The first message matching `pred` within the deadline (times kSlow); meshes on the way
// are applied, and one that does not apply fails the test.
template <class Pred>
std::optional<wire::Envelope> wait_for(client::Client& c, Pred pred,
                                       std::chrono::milliseconds limit = 10s) {
  const auto deadline = client::Clock::now() + limit * kSlow;
  while (client::Clock::now() < deadline) {
    auto m = c.receive(
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - client::Clock::now()));
    if (!m) return std::nullopt;
    if (m->has_chunk_mesh()) {
      const auto error = c.apply(m->chunk_mesh());
      EXPECT_FALSE(error) << *error;
    }
    if (pred(*m)) return m;
  }
  return std::nullopt;
}

// Sets the view and receives until its ViewReady (then every chunk of it is held): the
// messages in arrival order, the ViewReady last. Meshes are applied; a mesh that does not
// apply, an Error or no ViewReady in time fails the test.
// `lod_level` > 0: a level-of-detail view (PROTOCOL 4.10); coarse chunks are applied too.
inline std::vector<wire::Envelope> view_messages(client::Client& c, float x, float y, float z,
                                                 uint32_t radius, uint64_t view_id = 1,
                                                 uint32_t lod_level = 0, float lod_distance = 0) {
  c.send(client::make_set_view(x, y, z, radius, view_id, lod_level, lod_distance));
  std::vector<wire::Envelope> out;
  const auto deadline = client::Clock::now() + 120s * kSlow;
  while (client::Clock::now() < deadline) {
    auto m = c.receive(
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - client::Clock::now()));
    if (!m) break;
    if (m->has_chunk_mesh()) {
      const auto error = c.apply(m->chunk_mesh());
      EXPECT_FALSE(error) << *error;
    }
    if (m->has_chunk_unload()) c.forget(m->chunk_unload());
    EXPECT_FALSE(m->has_error()) << m->error().message();
    const bool done = m->has_view_ready() && m->view_ready().view_id() == view_id;
    out.push_back(std::move(*m));
    if (done) return out;
  }
  ADD_FAILURE() << "no ViewReady for view " << view_id
                << (c.closed() ? " (connection closed)" : " in time");
  return out;
}

inline wire::ViewReady view(client::Client& c, float x, float y, float z, uint32_t radius,
                            uint64_t view_id = 1) {
  auto messages = view_messages(c, x, y, z, radius, view_id);
  return messages.empty() || !messages.back().has_view_ready() ? wire::ViewReady{}
                                                               : messages.back().view_ready();
}

inline float surface_y(float x, float z, uint64_t seed = 1) {
  return world::TerrainGenerator(seed).height_at(static_cast<int>(x), static_cast<int>(z));
}

// Sends an edit and waits for its EditResult (meshes on the way are applied).
inline std::optional<wire::Envelope> edit_and_wait(client::Client& c, const wire::Envelope& edit,
                                                   std::chrono::milliseconds limit = 10s) {
  c.send(edit);
  return wait_for(
      c, [](const wire::Envelope& m) { return m.has_edit_result(); }, limit);
}

}  // namespace vox::test
