// Integration tests: a real voxeld on 127.0.0.1 (port 0), spoken to over TCP as a game
// client would. Every wait has a deadline.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "client/voxel_client.hpp"
#include "proto/framing.hpp"
#include "proto/mesh_codec.hpp"
#include "tests/session_test_util.hpp"

namespace vox::net {
namespace {

using namespace std::chrono_literals;
using client::Client;
using client::make_brush;

constexpr uint64_t kSeed = 1;
using test::connect_to;
using test::kSlow;
using test::player;
using test::surface_y;
using test::wait_for;

// Receives until `quiet` passes with nothing new (or `limit`); applies meshes. Returns the
// ChunkMesh messages in arrival order. Any decode failure fails the test.
std::vector<wire::Envelope> drain(Client& c, std::chrono::milliseconds quiet = 700ms,
                                  std::chrono::milliseconds limit = 30s) {
  std::vector<wire::Envelope> out;
  quiet *= kSlow;
  limit *= kSlow;
  const auto deadline = client::Clock::now() + limit;
  while (client::Clock::now() < deadline) {
    // The first message may take a while (terrain is generated on demand).
    auto m =
        c.receive(out.empty() ? std::min<std::chrono::milliseconds>(limit, 15s * kSlow) : quiet);
    if (!m) break;
    if (m->has_chunk_mesh()) {
      const auto error = c.apply(m->chunk_mesh());
      EXPECT_FALSE(error) << *error;
    }
    out.push_back(std::move(*m));
  }
  return out;
}

wire::Error::Code error_code(const std::optional<wire::Envelope>& m) {
  return m && m->has_error() ? m->error().code() : wire::Error::UNKNOWN;
}

TEST(Server, HandshakeReturnsWelcome) {
  test::ServerProcess server;
  Client c;
  c.connect("127.0.0.1", server.port(), 5s);
  const wire::Welcome w = c.handshake("alice", 5s);
  EXPECT_EQ(w.world_seed(), kSeed);
  EXPECT_EQ(w.chunk_size(), 32u);
  EXPECT_EQ(w.protocol_version(), 1u);
  EXPECT_EQ(w.mesh_format(), 1u);
  EXPECT_EQ(w.mesh_table_revision(), proto::kMeshTableRevision);
  EXPECT_GT(w.max_view_radius(), 0u);
  EXPECT_EQ(w.players(), 1u);
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(77);
  c.send(ping);
  auto pong = wait_for(c, [](const wire::Envelope& m) { return m.has_pong(); });
  ASSERT_TRUE(pong);
  EXPECT_EQ(pong->pong().nonce(), 77u);
}

TEST(Server, StreamsTheViewNearestFirst) {
  test::ServerProcess server;
  auto c = player(server, "viewer");
  const float y = surface_y(16, 16);
  const auto messages = test::view_messages(*c, 16, y, 16, 3);
  const world::ChunkCoord centre = world::chunk_of_voxel(16, static_cast<int>(std::floor(y)), 16);
  int64_t last = -1;
  size_t meshes = 0;
  for (const auto& m : messages) {
    if (!m.has_chunk_mesh()) continue;
    ++meshes;
    EXPECT_EQ(m.chunk_mesh().base_version(), 0u) << "a fresh client gets full meshes";
    const auto& k = m.chunk_mesh().coord();
    const int64_t d = (k.x() - centre.x) * (k.x() - centre.x) +
                      (k.y() - centre.y) * (k.y() - centre.y) +
                      (k.z() - centre.z) * (k.z() - centre.z);
    EXPECT_LE(d, 9);
    EXPECT_GE(d, last) << "meshes must arrive nearest first";
    last = d;
  }
  EXPECT_GT(meshes, 5u);
}

TEST(Server, EditByOneClientReachesAnotherAsAMatchingDelta) {
  test::ServerProcess server;
  auto a = player(server, "a");
  auto b = player(server, "b");
  const float y = surface_y(16, 16);
  test::view(*a, 16, y, 16, 2);
  test::view(*b, 16, y, 16, 2);
  auto result = test::edit_and_wait(*a, make_brush(42, 16.3f, y, 16.6f, 3, 1, false));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->edit_result().request_id(), 42u);
  EXPECT_EQ(result->edit_result().status(), wire::EditResult::ACCEPTED);
  ASSERT_GT(result->edit_result().changed_chunks_size(), 0);
  // B receives each changed chunk as a delta against what it held.
  std::set<std::tuple<int, int, int>> changed;
  for (const auto& k : result->edit_result().changed_chunks())
    changed.insert({k.x(), k.y(), k.z()});
  while (!changed.empty()) {
    auto m = wait_for(
        *b, [](const wire::Envelope& e) { return e.has_chunk_mesh(); }, 10s);
    ASSERT_TRUE(m) << changed.size() << " changed chunks did not reach b";
    EXPECT_NE(m->chunk_mesh().base_version(), 0u) << "b held the chunk: a delta";
    changed.erase(client::key_of(m->chunk_mesh().coord()));
  }
  // A fresh client receives the server's current meshes in full: B's state must match.
  auto c = player(server, "c");
  test::view(*c, 16, y, 16, 2);
  for (const auto& k : result->edit_result().changed_chunks()) {
    const auto key = std::make_tuple(k.x(), k.y(), k.z());
    ASSERT_TRUE(b->chunks().count(key) && c->chunks().count(key));
    EXPECT_EQ(b->chunks().at(key).version, c->chunks().at(key).version);
    EXPECT_EQ(b->chunks().at(key).encoding, c->chunks().at(key).encoding);
  }
}

TEST(Server, BurstOfEditsCoalescesToTheNewestVersion) {
  test::ServerProcess server;
  auto a = player(server, "burst");
  const float y = surface_y(40, 40);
  test::view(*a, 40, y, 40, 1);
  for (uint64_t i = 1; i <= 60; ++i)
    a->send(make_brush(i, 40.0f + static_cast<float>(i % 5), y, 40.0f, 2.5f, 1, i % 2 == 0));
  std::map<std::tuple<int, int, int>, uint64_t> last_version;
  size_t results = 0;
  const auto messages = drain(*a, 1000ms);
  for (const auto& m : messages) {
    if (m.has_edit_result()) ++results;
    if (!m.has_chunk_mesh()) continue;
    const auto& k = m.chunk_mesh().coord();
    auto& v = last_version[std::make_tuple(k.x(), k.y(), k.z())];
    EXPECT_GT(m.chunk_mesh().version(), v) << "an older version after a newer one";
    v = m.chunk_mesh().version();
  }
  EXPECT_EQ(results, 60u);
  auto fresh = player(server, "fresh");
  test::view(*fresh, 40, y, 40, 1);
  for (const auto& [key, held] : fresh->chunks()) {
    ASSERT_TRUE(a->chunks().count(key));
    EXPECT_EQ(a->chunks().at(key).version, held.version)
        << "the client must end with the newest version";
    EXPECT_EQ(a->chunks().at(key).encoding, held.encoding);
  }
}

TEST(Server, BadInputGetsSpecificErrors) {
  test::ServerProcess server({"--max-view-radius", "4"});
  {  // frame over the limit: FRAME_TOO_LARGE, then closed
    auto c = connect_to(server);
    const uint8_t header[4] = {0xFF, 0xFF, 0xFF, 0x7F};
    c->send_raw(header);
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              wire::Error::FRAME_TOO_LARGE);
    EXPECT_FALSE(c->receive(3s));
    EXPECT_TRUE(c->closed());
  }
  {  // unparsable bytes: MALFORMED
    auto c = connect_to(server);
    std::vector<uint8_t> frame;
    const uint8_t junk[] = {0xFF, 0xFF, 0xFF, 0xFF, 0x0F, 0x01};
    proto::append_frame(junk, frame);
    c->send_raw(frame);
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              wire::Error::MALFORMED);
  }
  {  // a message before Hello: NOT_HELLO
    auto c = connect_to(server);
    c->send(client::make_set_view(0, 0, 0, 1));
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              wire::Error::NOT_HELLO);
  }
  {  // wrong protocol version: BAD_VERSION
    auto c = connect_to(server);
    c->send(client::make_hello("old", 99));
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              wire::Error::BAD_VERSION);
  }
  auto c = player(server, "probe");
  auto expect_error = [&](const wire::Envelope& sent, wire::Error::Code code) {
    c->send(sent);
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              code);
  };
  expect_error(client::make_set_view(std::numeric_limits<float>::quiet_NaN(), 0, 0, 1),
               wire::Error::BAD_VALUE);
  expect_error(client::make_set_view(0, std::numeric_limits<float>::infinity(), 0, 1),
               wire::Error::BAD_VALUE);
  expect_error(client::make_set_view(0, 0, 0, 5),
               wire::Error::BAD_VALUE);  // radius over --max-view-radius
  expect_error(client::make_hello("again"), wire::Error::DUPLICATE_HELLO);
  {  // unknown fields: UNKNOWN_MESSAGE
    wire::Envelope ping;
    ping.mutable_ping()->set_nonce(1);
    std::string body = ping.SerializeAsString();
    body += std::string("\xF8\x07\x01", 3);  // field 127, varint 1: not in the schema
    std::vector<uint8_t> frame;
    proto::append_frame({reinterpret_cast<const uint8_t*>(body.data()), body.size()}, frame);
    c->send_raw(frame);
    EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
              wire::Error::UNKNOWN_MESSAGE);
  }
  {  // an empty Envelope: UNKNOWN_MESSAGE
    wire::Envelope empty;
    expect_error(empty, wire::Error::UNKNOWN_MESSAGE);
  }
  {  // an unknown enum value: UNKNOWN_ENUM, and the edit is refused
    wire::Envelope m;
    m.mutable_edit()->set_request_id(9);
    m.mutable_edit()->mutable_stamp()->set_shape(static_cast<wire::Stamp::Shape>(7));
    m.mutable_edit()->mutable_stamp()->set_radius(2);
    m.mutable_edit()->mutable_stamp()->set_material(3);
    c->send(m);
    auto result = wait_for(*c, [](const wire::Envelope& e) { return e.has_edit_result(); });
    ASSERT_TRUE(result);
    EXPECT_EQ(result->edit_result().status(), wire::EditResult::BAD_VALUE);
  }
  {  // NaN in an edit: refused with NOT_FINITE
    c->send(make_brush(10, std::numeric_limits<float>::quiet_NaN(), 0, 0, 2, 1, false));
    auto result = wait_for(*c, [](const wire::Envelope& e) { return e.has_edit_result(); });
    ASSERT_TRUE(result);
    EXPECT_EQ(result->edit_result().status(), wire::EditResult::NOT_FINITE);
  }
  // After all that, the connection and the server still work.
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(5);
  c->send(ping);
  EXPECT_TRUE(wait_for(*c, [](const wire::Envelope& m) { return m.has_pong(); }));
  EXPECT_TRUE(server.running());
}

TEST(Server, RefusesClientsOverTheLimitAndSilentHandshakes) {
  test::ServerProcess server({"--max-clients", "2", "--handshake-timeout-ms", "300"});
  auto a = player(server, "a");
  auto b = player(server, "b");
  auto c = connect_to(server);  // connecting is fine: players are counted at Hello
  wire::Envelope hello;
  hello.mutable_hello()->set_protocol_version(1);
  hello.mutable_hello()->set_player_name("c");
  c->send(hello);
  EXPECT_EQ(error_code(wait_for(*c, [](const wire::Envelope& m) { return m.has_error(); })),
            wire::Error::SERVER_FULL);
  b.reset();  // a slot frees up
  auto silent = std::make_unique<Client>();
  const auto deadline = client::Clock::now() + 5s;
  std::optional<wire::Envelope> error;
  while (client::Clock::now() < deadline && !error) {  // the freed slot may take a moment
    silent = connect_to(server);
    error = wait_for(
        *silent, [](const wire::Envelope& m) { return m.has_error(); }, 3s);
    if (error_code(error) == wire::Error::SERVER_FULL) error.reset();
  }
  EXPECT_EQ(error_code(error), wire::Error::HANDSHAKE_TIMEOUT);
  EXPECT_TRUE(server.running());
}

TEST(Server, ShutsDownGracefullyOnSigterm) {
  test::ServerProcess server;
  auto c = player(server, "stayer");
  test::view(*c, 0, surface_y(0, 0), 0, 1);
  const int code = server.terminate();
  EXPECT_EQ(code, 0);
  EXPECT_EQ(error_code(wait_for(
                *c, [](const wire::Envelope& m) { return m.has_error(); }, 5s)),
            wire::Error::SHUTTING_DOWN);
}

}  // namespace
}  // namespace vox::net

namespace vox::net {
namespace {

TEST(Server, DisconnectsIdleClientsAndKeepsServingOthers) {
  test::ServerProcess server({"--idle-timeout-ms", "400"});
  auto quiet = player(server, "quiet");
  auto error = wait_for(
      *quiet, [](const wire::Envelope& m) { return m.has_error(); }, 5s);
  EXPECT_EQ(error_code(error), wire::Error::IDLE_TIMEOUT);
  EXPECT_FALSE(quiet->receive(2s));
  EXPECT_TRUE(quiet->closed());
  auto next = player(server, "next");  // the server is still there
  EXPECT_FALSE(next->closed());
}

}  // namespace
}  // namespace vox::net

namespace vox::net {
namespace {

// A client flooding edits cannot queue unbounded work: past the in-flight limit its edits
// are refused with TOO_MANY_EDITS, every edit still gets exactly one result, and the
// server goes on serving.
TEST(Server, EditFloodIsBoundedPerClient) {
  test::ServerProcess server({"--edit-budget", "0"});  // the in-flight limit alone
  auto c = player(server, "flood");
  const float y = surface_y(16, 16);
  constexpr uint64_t kEdits = 2000;
  for (uint64_t i = 1; i <= kEdits; ++i) {
    wire::Envelope m;
    m.mutable_edit()->set_request_id(i);
    auto* x = m.mutable_edit()->mutable_explosion();
    x->mutable_center()->set_x(16.0f + static_cast<float>(i % 64));
    x->mutable_center()->set_y(y);
    x->mutable_center()->set_z(16.0f);
    x->set_radius(16);
    x->set_power(0.5f);
    c->send(m);
  }
  std::set<uint64_t> answered;
  size_t limited = 0;
  while (answered.size() < kEdits) {
    auto r = wait_for(
        *c, [](const wire::Envelope& m) { return m.has_edit_result(); }, 60s);
    ASSERT_TRUE(r) << answered.size() << " results";
    EXPECT_TRUE(answered.insert(r->edit_result().request_id()).second) << "one result per edit";
    limited += r->edit_result().status() == wire::EditResult::TOO_MANY_EDITS ? 1 : 0;
  }
  EXPECT_GT(limited, 0u) << "2,000 radius-16 explosions at once must hit the in-flight limit";
  wire::Envelope ping;
  ping.mutable_ping()->set_nonce(3);
  c->send(ping);
  EXPECT_TRUE(wait_for(*c, [](const wire::Envelope& m) { return m.has_pong(); }));
}

}  // namespace
}  // namespace vox::net
