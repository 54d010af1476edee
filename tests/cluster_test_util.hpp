// Helpers of the cluster tests (tests/cluster_node_test.cpp, tests/cluster_failover_test.cpp):
// a real PostgreSQL and nats-server, node configuration files, voxeld processes with
// --cluster FILE, and players speaking the protocol. Zones are 2 x 2 chunks here, so the
// edits near x = 64 and z = 64 cross zone borders and are logged as one part per zone.
#pragma once

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "server/cluster/zone_wire.hpp"
#include "server/net/wire_convert.hpp"
#include "server/store/edit_codec.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/zone.hpp"
#include "tests/nats_server.hpp"
#include "tests/postgres_server.hpp"
#include "tests/session_test_util.hpp"
#include "tests/temp_dir.hpp"

namespace vox::test {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

inline constexpr int kZoneChunks = 2;

// A node's configuration file, readable by its owner only (it holds passwords).
inline std::string node_config(const TempDir& tmp, const std::string& node,
                               const std::string& database, const NatsServer& nats,
                               const std::string& more = "") {
  const fs::path path = tmp / (node + ".conf");
  std::ofstream(path) << "# a test node\n"
                      << "database = " << database << "\n"
                      << "nats = " << nats.url() << "\n"
                      << "nats_user = " << NatsServer::kUser << "\n"
                      << "nats_password = " << NatsServer::kPassword << "\n"
                      << "world = test\n"
                      << "node = " << node << "\n"
                      << "lease_ms = 1000\n"
                      << "zone_chunks = " << kZoneChunks << "\n"
                      << more;
  ::chmod(path.c_str(), 0600);
  return path.string();
}

// An edit message of `request` whose centre is at (x, surface, z).
inline wire::Envelope edit_at(uint64_t request, float x, float z,
                              const std::function<wire::Vec3*(wire::Edit*)>& shape) {
  wire::Envelope m;
  m.mutable_edit()->set_request_id(request);
  wire::Vec3* center = shape(m.mutable_edit());
  center->set_x(x);
  center->set_y(surface_y(x, z));
  center->set_z(z);
  return m;
}

inline wire::Envelope brush(uint64_t request, float x, float z, int material, float radius = 5.5f) {
  return edit_at(request, x, z, [&](wire::Edit* e) {
    auto* b = e->mutable_brush();
    b->set_radius(radius);
    b->set_strength(0.8f);
    b->set_material(static_cast<uint32_t>(material));
    return b->mutable_center();
  });
}

inline wire::Envelope explosion(uint64_t request, float x, float z) {
  return edit_at(request, x, z, [](wire::Edit* e) {
    auto* x1 = e->mutable_explosion();
    x1->set_radius(7);
    x1->set_power(1.3f);
    return x1->mutable_center();
  });
}

inline wire::Envelope smooth(uint64_t request, float x, float z) {
  return edit_at(request, x, z, [](wire::Edit* e) {
    auto* s = e->mutable_smooth();
    s->set_radius(6);
    s->set_strength(0.5f);
    return s->mutable_center();
  });
}

// Brushes and explosions on and across the zone borders at x = 64 and z = 64, a paint-like
// brush on top of them, and a smooth inside one zone.
inline std::vector<wire::Envelope> border_edits() {
  std::vector<wire::Envelope> out;
  uint64_t id = 1;
  for (const float x : {58.0f, 63.5f, 66.0f})
    for (const float z : {61.0f, 64.0f}) out.push_back(brush(id++, x, z, 4));
  out.push_back(explosion(id++, 64.0f, 64.0f));
  out.push_back(explosion(id++, 70.0f, 58.0f));
  out.push_back(brush(id++, 64.0f, 60.0f, 2, 8.0f));
  out.push_back(smooth(id++, 40.0f, 40.0f));
  return out;
}

// Sends the edit until it is accepted: a node refuses edits (STORAGE_UNAVAILABLE) in a
// zone it is still taking or loading. Returns the last result.
inline wire::EditResult edit_until_accepted(client::Client& c, const wire::Envelope& edit,
                                            std::chrono::seconds limit = 20s) {
  const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
  wire::EditResult last;
  for (;;) {
    const auto r = edit_and_wait(c, edit);
    if (!r) return last;
    last = r->edit_result();
    const bool again = last.status() == wire::EditResult::STORAGE_UNAVAILABLE ||
                       last.status() == wire::EditResult::RATE_LIMITED;  // a long replay
    if (!again || std::chrono::steady_clock::now() > deadline) return last;
    std::this_thread::sleep_for(std::max<std::chrono::milliseconds>(
        100ms, std::chrono::milliseconds(last.retry_after_ms())));
  }
}

inline void apply_all(const ServerProcess& server, const std::vector<wire::Envelope>& edits) {
  auto c = player(server, "editor");
  for (const auto& e : edits) {
    const wire::EditResult r = edit_until_accepted(*c, e);
    ASSERT_EQ(r.status(), wire::EditResult::ACCEPTED) << r.reason();
  }
}

using Seen = std::map<client::ChunkKey, std::vector<uint8_t>>;

// Every chunk's encoding of a radius-2 view around (64, 64), as a fresh client gets it.
inline Seen world_seen(const ServerProcess& server) {
  auto c = player(server, "viewer");
  view(*c, 64, surface_y(64, 64), 64, 2);
  Seen out;
  for (const auto& [key, held] : c->chunks()) out[key] = held.encoding;
  return out;
}

// What a single node shows after the same edits.
inline Seen single_node_after(const std::vector<wire::Envelope>& edits) {
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, edits);
  return world_seen(fresh);
}

// A node shows a zone as its log has it once it holds the zone (it asks for the zones its
// players view): asks again until it does, or the time is up.
inline Seen eventually_seen(const ServerProcess& server, const Seen& expected,
                            std::chrono::seconds limit = 20s) {
  const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
  Seen seen;
  while (std::chrono::steady_clock::now() < deadline) {
    seen = world_seen(server);
    if (seen == expected) break;
    std::this_thread::sleep_for(300ms);
  }
  return seen;
}

// Whether `pred` holds within a while (a node follows a zone a moment after its first view).
template <typename Pred>
inline bool eventually(const ServerProcess*, Pred pred, std::chrono::seconds limit = 10s) {
  const auto deadline = std::chrono::steady_clock::now() + limit * kSlow;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(300ms);
  }
  return true;
}

// An edit message's world edit as the store encodes it: what a zone's log holds.
inline std::string encoding_of(const wire::Envelope& m) {
  const auto bytes = store::encode_edit(*net::edit_from_wire(m.edit()).edit);
  return {bytes.begin(), bytes.end()};
}

struct Cluster {
  std::string database = fresh_shared_database("cluster_node");
  NatsServer nats;
  TempDir tmp{"cluster_node"};
  // `more`: further `key = value` lines.
  std::string config(const std::string& node, const std::string& more = "") const {
    return node_config(tmp, node, database, nats, more);
  }
};

// The first zone along x (z = 0) that `node` ranks first for among {a, b}, and the voxel
// column at its middle.
inline std::pair<float, float> middle_of_a_zone_of(const std::string& node) {
  const std::vector<std::string> nodes = {"a", "b"};
  world::ZoneId zone{0, 0};
  for (int32_t x = 0; x < 16; ++x) {
    if (nodes[*world::first_ranked({x, 0}, nodes)] == node) {
      zone = {x, 0};
      break;
    }
  }
  const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
  return {(static_cast<float>(zone.x) + 0.5f) * side, 0.5f * side};
}

inline Seen held_by(const client::Client& c) {
  Seen out;
  for (const auto& [key, held] : c.chunks()) out[key] = held.encoding;
  return out;
}

inline Seen view_of(const ServerProcess& server, float x, float z) {
  auto viewer = player(server, "viewer");
  view(*viewer, x, surface_y(x, z), z, 1);
  return held_by(*viewer);
}

// Players editing `zones` through `nodes` (one player per node), one edit at a time each,
// until stopped; every edit unique (its centre), well inside its zone. Records what was
// sent and accepted, and when.
class EditingLoad {
 public:
  using Clock = std::chrono::steady_clock;
  EditingLoad(std::vector<const ServerProcess*> nodes, std::vector<world::ZoneId> zones)
      : zones_(std::move(zones)) {
    for (size_t p = 0; p < nodes.size(); ++p)
      threads_.emplace_back([this, node = nodes[p], p] { play(*node, static_cast<int>(p)); });
  }
  ~EditingLoad() { stop(); }
  void stop() {
    stop_ = true;
    for (auto& t : threads_)
      if (t.joinable()) t.join();
  }
  size_t accepted() const {
    std::lock_guard lock(mutex_);
    return accepted_.size();
  }
  int refused() const { return refused_; }
  // From `t` to the answer of the first edit sent after it and accepted (ms; -1: none).
  double first_accepted_after_ms(Clock::time_point t) const {
    std::lock_guard lock(mutex_);
    for (const Accepted& a : accepted_) {
      if (a.sent > t) return std::chrono::duration<double, std::milli>(a.answered - t).count();
    }
    return -1;
  }
  // The longest wait between accepted answers after `t` (a stall), in ms.
  double longest_gap_after_ms(Clock::time_point t) const {
    std::lock_guard lock(mutex_);
    double longest = 0;
    Clock::time_point last = t;
    for (const Accepted& a : accepted_) {
      if (a.answered <= t) continue;
      longest =
          std::max(longest, std::chrono::duration<double, std::milli>(a.answered - last).count());
      last = a.answered;
    }
    return longest;
  }
  // Checks the zones' logs: sequences 1, 2, ... without a gap, every accepted edit in them
  // exactly once and nothing nobody sent. Returns the logged edits, zone by zone in log
  // order (zones apart, so their order between zones does not matter), for a replay.
  std::vector<wire::Envelope> check_logs(const std::string& database) const {
    std::lock_guard lock(mutex_);
    store::ZoneLeases reader(database, "test-reader", 3000ms);
    std::map<std::string, int> logged;
    std::vector<wire::Envelope> replay;
    for (const world::ZoneId zone : zones_) {
      uint64_t expect_seq = 1;
      for (const store::ZoneRecord& r : reader.read_log(zone, 0)) {
        EXPECT_EQ(r.seq, expect_seq++);
        const auto e = store::decode_zone_edit(r);
        EXPECT_TRUE(e);
        if (!e) continue;
        const auto bytes = store::encode_edit(e->edit);
        const std::string key(bytes.begin(), bytes.end());
        ++logged[key];
        const auto it = sent_.find(key);
        EXPECT_TRUE(it != sent_.end()) << "a logged edit nobody sent";
        if (it != sent_.end()) replay.push_back(it->second);
      }
    }
    for (const Accepted& a : accepted_)
      EXPECT_EQ(logged[a.key], 1) << "an accepted edit logged so often";
    for (const auto& [key, n] : logged) EXPECT_LE(n, 1) << "an edit logged twice";
    return replay;
  }

 private:
  struct Accepted {
    std::string key;  // encoding_of
    world::ZoneId zone;
    Clock::time_point sent, answered;
  };
  wire::Envelope edit_for(int player, int i) const {
    const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
    const world::ZoneId zone = zones_[static_cast<size_t>(i) % zones_.size()];
    const float x = (static_cast<float>(zone.x) + 0.3f + 0.02f * static_cast<float>(i % 20)) * side;
    // Each player's centres keep to a line of their own, an eighth of the zone from the
    // next player's, in one half of the zone for 600 edits and then in the other (a long
    // run's chunks go idle, are evicted and edited again); unique for 6,000 edits a player
    // (0.01 voxel a step once met the next player's line after 1,280).
    const float z = (static_cast<float>(zone.z) + ((i / 600) % 2 ? 0.5625f : 0.0625f) +
                     0.125f * static_cast<float>(player % 3)) *
                        side +
                    0.0005f * static_cast<float>(i % 6000);
    return brush(static_cast<uint64_t>(i + 1), x, z, 1 + (i % 5), 2.5f);
  }
  void play(const ServerProcess& node, int p) {
    auto client = player(node, "editor-" + std::to_string(p));
    for (int i = 0; !stop_; ++i) {
      const wire::Envelope e = edit_for(p, i);
      const std::string key = encoding_of(e);
      {
        std::lock_guard lock(mutex_);
        sent_[key] = e;
      }
      const Clock::time_point sent = Clock::now();
      const auto r = edit_and_wait(*client, e, 15s);
      if (!r) break;
      if (r->edit_result().status() != wire::EditResult::ACCEPTED) {
        ++refused_;
        std::this_thread::sleep_for(50ms);
        continue;
      }
      std::lock_guard lock(mutex_);
      accepted_.push_back(
          {key, zones_[static_cast<size_t>(i) % zones_.size()], sent, Clock::now()});
    }
  }

  const std::vector<world::ZoneId> zones_;
  mutable std::mutex mutex_;  // guards sent_, accepted_
  std::map<std::string, wire::Envelope> sent_;
  std::vector<Accepted> accepted_;  // in the order answered
  std::atomic<bool> stop_{false};
  std::atomic<int> refused_{0};
  std::vector<std::thread> threads_;
};

// Each of `nodes` shows, in the middle of each of `zones`, what a single node shows after
// `replay` (the zones' logged edits): every replica equals a replay of the log.
inline void expect_nodes_show(const std::vector<const ServerProcess*>& nodes,
                              const std::vector<world::ZoneId>& zones,
                              const std::vector<wire::Envelope>& replay) {
  ServerProcess fresh({"--in-memory"});
  apply_all(fresh, replay);
  const float side = static_cast<float>(kZoneChunks * world::kChunkSize);
  for (const world::ZoneId zone : zones) {
    const float x = (static_cast<float>(zone.x) + 0.5f) * side,
                z = (static_cast<float>(zone.z) + 0.5f) * side;
    const Seen expected = view_of(fresh, x, z);
    for (const ServerProcess* node : nodes) {
      EXPECT_TRUE(eventually(node, [&] { return view_of(*node, x, z) == expected; }))
          << "a node's replica of zone (" << zone.x << ", " << zone.z << ") differs from its log";
    }
  }
}

// The first `n` zones along x (z = 0) that `node` ranks first for among `nodes`.
inline std::vector<world::ZoneId> zones_ranked_first_by(const std::string& node,
                                                        const std::vector<std::string>& nodes,
                                                        size_t n) {
  std::vector<world::ZoneId> out;
  for (int32_t x = 0; x < 64 && out.size() < n; ++x) {
    if (nodes[*world::first_ranked({x, 0}, nodes)] == node) out.push_back({x, 0});
  }
  return out;
}

// Two zones side by side along x (z = 0), the first ranked first by node a among {a, b}
// and the second by b: where an edit across their border has parts on both nodes.
struct ZonesApart {
  world::ZoneId of_a, of_b;
  float border_x() const {  // the voxel x of the border between them
    return static_cast<float>(std::max(of_a.x, of_b.x) * kZoneChunks * world::kChunkSize);
  }
  float middle_z() const { return 0.5f * static_cast<float>(kZoneChunks * world::kChunkSize); }
};
inline ZonesApart zones_held_apart() {
  const std::vector<std::string> nodes = {"a", "b"};
  for (int32_t x = 0; x < 64; ++x) {
    const size_t here = *world::first_ranked({x, 0}, nodes);
    const size_t next = *world::first_ranked({x + 1, 0}, nodes);
    if (here != next)
      return here == 0 ? ZonesApart{{x, 0}, {x + 1, 0}} : ZonesApart{{x + 1, 0}, {x, 0}};
  }
  return {};
}

// Four zones around a corner that three nodes {a, b, c} hold between them, each node at
// least one: where edits inside a zone, across two and across four have their parts on
// different nodes.
struct CornerOfThree {
  world::ZoneId low;  // the zone below and left of the corner; the others are +x, +z, +xz
  std::vector<world::ZoneId> zones() const {
    return {low, {low.x + 1, low.z}, {low.x, low.z + 1}, {low.x + 1, low.z + 1}};
  }
  float corner(int32_t zone) const {  // the corner's voxel x (or z, given low.z)
    return static_cast<float>((zone + 1) * kZoneChunks * world::kChunkSize);
  }
};
inline std::optional<CornerOfThree> corner_of_three() {
  const std::vector<std::string> nodes = {"a", "b", "c"};
  for (int32_t x = 0; x < 32; ++x)
    for (int32_t z = 0; z < 32; ++z) {
      std::set<size_t> holders;
      for (const world::ZoneId zone : CornerOfThree{{x, z}}.zones())
        holders.insert(*world::first_ranked(zone, nodes));
      if (holders.size() == 3) return CornerOfThree{{x, z}};
    }
  return std::nullopt;
}

// How often each edit id is in each of `zones`' logs (ids 0 left out).
inline std::map<std::pair<world::ZoneId, uint64_t>, int> edit_ids_logged(
    const std::string& database, const std::vector<world::ZoneId>& zones) {
  store::ZoneLeases reader(database, "test-reader", 3000ms);
  std::map<std::pair<world::ZoneId, uint64_t>, int> out;
  for (const world::ZoneId zone : zones) {
    for (const store::ZoneRecord& r : reader.read_log(zone, 0)) {
      const auto e = store::decode_zone_edit(r);
      EXPECT_TRUE(e);
      EXPECT_EQ(e ? e->edit_id : 0, r.edit_id) << "a record's edit id differs from its row's";
      if (r.edit_id != 0) ++out[{zone, r.edit_id}];
    }
  }
  return out;
}

}  // namespace vox::test
