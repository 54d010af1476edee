#include "server/pipeline/subscribers.hpp"

namespace vox::pipeline {

uint64_t Subscribers::subscribe(Subscriber s) {
  std::lock_guard lock(mutex_);
  subscribers_.emplace_back(next_id_, std::move(s));
  return next_id_++;
}

uint64_t Subscribers::subscribe_lod(LodSubscriber s) {
  std::lock_guard lock(mutex_);
  lod_subscribers_.emplace_back(next_id_, std::move(s));
  return next_id_++;
}

void Subscribers::unsubscribe(uint64_t id) {
  {
    std::lock_guard lock(mutex_);
    std::erase_if(subscribers_, [id](const auto& p) { return p.first == id; });
    std::erase_if(lod_subscribers_, [id](const auto& p) { return p.first == id; });
  }
  if (caller_.load() != std::this_thread::get_id()) std::lock_guard wait(calling_);
}

void Subscribers::notify(const std::vector<world::ChunkCoord>& published) const {
  if (published.empty()) return;
  std::vector<Subscriber> copy;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, s] : subscribers_) copy.push_back(s);
  }
  std::lock_guard calling(calling_);
  caller_.store(std::this_thread::get_id());
  for (const auto& s : copy) s(published);
  caller_.store({});
}

void Subscribers::notify_lod(const LodPublication& publication) const {
  std::vector<LodSubscriber> copy;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, s] : lod_subscribers_) copy.push_back(s);
  }
  std::lock_guard calling(calling_);
  caller_.store(std::this_thread::get_id());
  for (const auto& s : copy) s(publication);
  caller_.store({});
}

}  // namespace vox::pipeline
