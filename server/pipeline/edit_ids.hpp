// Edit ids a world has applied (docs/PROTOCOL.md 4.4, "edit_id"; docs/CLUSTER.md): the
// last `capacity` noted, oldest forgotten first. A resent edit whose id is here is answered
// as applied, not applied again. Not thread-safe: its owner says which thread (a single
// node's pipeline thread; a cluster's ZoneTable, under its lock).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <string_view>
#include <unordered_map>
#include <utility>

namespace vox::pipeline {

class EditIds {
 public:
  explicit EditIds(size_t capacity = 65536) : capacity_(capacity) {}
  bool has(uint64_t id) const { return id != 0 && when_.count(id) != 0; }
  void note(uint64_t id);    // 0: nothing
  void forget(uint64_t id);  // an edit undone (its append failed)
  size_t size() const { return when_.size(); }
  // The world's id of a player's edit that carries `client_id` (never 0; 0 for none): a
  // hash keyed by a secret (SipHash-2-4), so that no player can choose a client id whose
  // world id is another player's; every node of a cluster has the same key, so a resend
  // through another node finds it.
  using Key = std::array<uint8_t, 16>;
  static uint64_t of_player(const Key& key, std::string_view player, uint64_t client_id);
  static Key random_key();                              // a single node's, for its run
  static Key key_from_secret(std::string_view secret);  // a cluster's, from a shared secret

 private:
  size_t capacity_;
  std::unordered_map<uint64_t, uint64_t> when_;      // id -> its last note (a counter)
  std::deque<std::pair<uint64_t, uint64_t>> order_;  // (id, note), oldest first
  uint64_t notes_ = 0;
};

}  // namespace vox::pipeline
