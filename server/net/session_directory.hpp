// Every live session by its number: what the publish fan-out, shutdown, the admin's player
// list and kicks go through. Holds weak references (a session ends on its own); expired
// entries are dropped as the live ones are taken, and before each addition once they could
// outnumber the live ones. Any thread (one leaf mutex; no session is called under it).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

namespace vox::net {

template <typename Session>
class SessionDirectory {
 public:
  void add(uint64_t id, const std::shared_ptr<Session>& session) {
    std::lock_guard lock(mutex_);
    if (sessions_.size() >= sweep_at_) {
      std::erase_if(sessions_, [](const auto& p) { return p.second.expired(); });
      sweep_at_ = 2 * sessions_.size() + 64;
    }
    sessions_.emplace(id, session);
  }
  // The live sessions, in no order.
  std::vector<std::shared_ptr<Session>> live() {
    std::vector<std::shared_ptr<Session>> out;
    std::lock_guard lock(mutex_);
    out.reserve(sessions_.size());
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      if (auto s = it->second.lock()) {
        out.push_back(std::move(s));
        ++it;
      } else {
        it = sessions_.erase(it);
      }
    }
    return out;
  }
  std::shared_ptr<Session> find(uint64_t id) const {
    std::lock_guard lock(mutex_);
    const auto it = sessions_.find(id);
    return it == sessions_.end() ? nullptr : it->second.lock();
  }
  size_t count() const {  // live ones
    std::lock_guard lock(mutex_);
    size_t n = 0;
    for (const auto& [id, weak] : sessions_) n += weak.expired() ? 0 : 1;
    return n;
  }

 private:
  mutable std::mutex mutex_;
  size_t sweep_at_ = 64;
  std::unordered_map<uint64_t, std::weak_ptr<Session>> sessions_;
};

}  // namespace vox::net
