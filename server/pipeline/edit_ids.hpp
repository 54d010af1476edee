// Edit ids a world has applied (docs/PROTOCOL.md 4.4, "edit_id"; docs/CLUSTER.md): the
// last `capacity` noted, oldest forgotten first. A resent edit whose id is here is answered
// as applied, not applied again. Not thread-safe: its owner says which thread (a single
// node's pipeline thread; a cluster's ZoneTable, under its lock).
#pragma once

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
  // The world's id of a player's edit that carries `client_id` (never 0; 0 for none): one
  // fixed hash every node computes alike, so a resend through another node finds it.
  static uint64_t of_player(std::string_view player, uint64_t client_id);

 private:
  size_t capacity_;
  std::unordered_map<uint64_t, uint64_t> when_;      // id -> its last note (a counter)
  std::deque<std::pair<uint64_t, uint64_t>> order_;  // (id, note), oldest first
  uint64_t notes_ = 0;
};

}  // namespace vox::pipeline
