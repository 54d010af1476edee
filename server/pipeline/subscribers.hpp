// Who hears of new mesh versions: subscribers of level-0 chunks and of level-of-detail
// meshes, called on the pipeline thread after each publication with what was published.
// They must not block (post to your own executor). subscribe/unsubscribe: any thread;
// notify: the pipeline thread, outside any of the pipeline's locks.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/lod_mesh_store.hpp"
#include "server/world/chunk_coord.hpp"

namespace vox::pipeline {

// Level-of-detail keys published, and routed to the owners whose layouts want them (by
// owner), so that a session hears only of its own keys. When the pipeline takes an owner's
// new wants, the owner hears again of those published before (with no keys in `keys`).
using LodKeys = std::shared_ptr<const std::vector<LodKey>>;  // posted to a session as is
struct LodPublication {
  std::vector<LodKey> keys;
  std::vector<std::pair<LoadOwner, LodKeys>> by_owner;
};

class Subscribers {
 public:
  using Subscriber = std::function<void(const std::vector<world::ChunkCoord>&)>;
  using LodSubscriber = std::function<void(const LodPublication&)>;

  uint64_t subscribe(Subscriber s);         // any thread
  uint64_t subscribe_lod(LodSubscriber s);  // any thread
  // Any thread; either kind. Returns once no call of that subscriber is under way.
  void unsubscribe(uint64_t id);
  void notify(const std::vector<world::ChunkCoord>& published) const;  // none: no call
  void notify_lod(const LodPublication& publication) const;

 private:
  mutable std::mutex mutex_;  // leaf lock; callbacks run on a copy, outside it
  // Held while callbacks run (notify's thread), so that unsubscribe() returns only once
  // no call of the subscriber it removed is under way (one on another thread: the
  // subscriber may be destroyed next). Not waited for from within a callback.
  mutable std::mutex calling_;
  mutable std::atomic<std::thread::id> caller_{};
  std::vector<std::pair<uint64_t, Subscriber>> subscribers_;
  std::vector<std::pair<uint64_t, LodSubscriber>> lod_subscribers_;
  uint64_t next_id_ = 1;
};

}  // namespace vox::pipeline
