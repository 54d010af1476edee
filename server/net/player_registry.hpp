// Which connection holds each authenticated player id: a second connection with the same
// id replaces the first (docs/PROTOCOL.md §4.8), so one player cannot be in the world
// twice nor keep a stale connection that a reconnect would have to wait out. One entry
// per player (bounded by --max-clients); the holder removes its entry when it ends.
// Any thread (one leaf mutex; no callback runs under it).
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

namespace vox::net {

template <typename Session>
class PlayerRegistry {
 public:
  // `session` now holds `player_id`; returns the session that held it before, if it is
  // still alive (the caller tells it to go).
  std::shared_ptr<Session> claim(const std::string& player_id,
                                 const std::shared_ptr<Session>& session) {
    std::lock_guard lock(mutex_);
    std::weak_ptr<Session>& slot = holders_[player_id];
    std::shared_ptr<Session> previous = slot.lock();
    slot = session;
    return previous == session ? nullptr : previous;
  }
  // `session` ends: its entry goes, unless another session claimed the id since.
  void release(const std::string& player_id, const Session* session) {
    std::lock_guard lock(mutex_);
    auto it = holders_.find(player_id);
    if (it == holders_.end()) return;
    const std::shared_ptr<Session> holder = it->second.lock();
    if (!holder || holder.get() == session) holders_.erase(it);
  }
  size_t size() const {
    std::lock_guard lock(mutex_);
    return holders_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::unordered_map<std::string, std::weak_ptr<Session>> holders_;
};

}  // namespace vox::net
