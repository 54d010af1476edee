#include "server/pipeline/mesh_store.hpp"

#include "proto/zstd_codec.hpp"

namespace vox::pipeline {

size_t MeshVersion::memory_bytes() const {
  return sizeof(MeshVersion) + encoding.capacity() + full_frame.capacity();
}

namespace {

proto::ZstdCodec& thread_codec() {  // one per thread, for deltas and full frames
  thread_local proto::ZstdCodec zstd;
  return zstd;
}

}  // namespace

MeshVersion::~MeshVersion() {
  if (!delta_account_) return;
  size_t bytes = full_accounted_;
  for (const auto& [from, delta] : deltas_) bytes += delta->capacity();
  delta_account_->fetch_sub(bytes, std::memory_order_relaxed);
}

std::shared_ptr<const std::vector<uint8_t>> MeshVersion::delta_from(const MeshVersion& base) const {
  {
    std::lock_guard lock(deltas_mutex_);
    for (const auto& [from, delta] : deltas_) {
      if (from == base.version) return delta;
    }
  }
  auto delta = std::make_shared<std::vector<uint8_t>>();
  thread_codec().compress(encoding, base.encoding, *delta);
  std::lock_guard lock(deltas_mutex_);
  for (const auto& [from, existing] : deltas_) {
    if (from == base.version) return existing;  // another thread made it meanwhile
  }
  constexpr size_t kKeptDeltas = 8;  // the most recent bases; older clients get a fresh one made
  if (deltas_.size() >= kKeptDeltas) {
    if (delta_account_)
      delta_account_->fetch_sub(deltas_.front().second->capacity(), std::memory_order_relaxed);
    deltas_.erase(deltas_.begin());
  }
  deltas_.emplace_back(base.version, delta);
  if (delta_account_) delta_account_->fetch_add(delta->capacity(), std::memory_order_relaxed);
  return delta;
}

void MeshVersion::premake_delta(const MeshVersion& base, proto::ZstdCodec& zstd) {
  thread_local std::vector<uint8_t> frame;  // compress() sizes it for the worst case
  zstd.compress(encoding, base.encoding, frame);
  auto delta = std::make_shared<const std::vector<uint8_t>>(frame.begin(), frame.end());
  std::lock_guard lock(deltas_mutex_);  // not published: nobody else holds it
  deltas_.emplace_back(base.version, std::move(delta));
}

void MeshVersion::attach_account(std::shared_ptr<std::atomic<size_t>> account) const {
  std::lock_guard lock(deltas_mutex_);
  size_t premade = 0;
  for (const auto& [from, delta] : deltas_) premade += delta->capacity();
  if (premade > 0) account->fetch_add(premade, std::memory_order_relaxed);
  delta_account_ = std::move(account);
}

std::span<const uint8_t> MeshVersion::full() const {
  if (!full_frame.empty()) return full_frame;
  {
    std::lock_guard lock(deltas_mutex_);
    if (lazy_full_) return *lazy_full_;
  }
  thread_local std::vector<uint8_t> frame;       // compress() sizes it for the worst case
  thread_codec().compress(encoding, {}, frame);  // outside the lock
  auto made = std::make_unique<const std::vector<uint8_t>>(frame.begin(), frame.end());
  std::lock_guard lock(deltas_mutex_);
  if (!lazy_full_) {  // else another thread made it meanwhile
    if (delta_account_) {
      full_accounted_ = made->capacity();
      delta_account_->fetch_add(full_accounted_, std::memory_order_relaxed);
    }
    lazy_full_ = std::move(made);
  }
  return *lazy_full_;
}

MeshVersionPtr MeshStore::get(world::ChunkCoord c) const {
  Shard& s = shard(c);
  std::lock_guard lock(s.mutex);
  auto it = s.meshes.find(c);
  return it == s.meshes.end() ? nullptr : it->second;
}

void MeshStore::publish(MeshVersionPtr mesh) {
  const size_t added = mesh->memory_bytes();
  mesh->attach_account(delta_bytes_);  // before any reader can see it
  if (mesh->version > newest_.load(std::memory_order_relaxed))
    newest_.store(mesh->version, std::memory_order_release);
  MeshVersionPtr old;  // released after the lock, so a last reference is freed outside it
  {
    Shard& s = shard(mesh->coord);
    std::lock_guard lock(s.mutex);
    auto& slot = s.meshes[mesh->coord];
    old = std::move(slot);
    slot = std::move(mesh);
  }
  if (old) {
    bytes_.fetch_sub(old->memory_bytes(), std::memory_order_relaxed);
  } else {
    count_.fetch_add(1, std::memory_order_relaxed);
  }
  bytes_.fetch_add(added, std::memory_order_relaxed);
}

void MeshStore::erase(world::ChunkCoord c) {
  MeshVersionPtr old;
  {
    Shard& s = shard(c);
    std::lock_guard lock(s.mutex);
    auto it = s.meshes.find(c);
    if (it == s.meshes.end()) return;
    old = std::move(it->second);
    s.meshes.erase(it);
  }
  count_.fetch_sub(1, std::memory_order_relaxed);
  bytes_.fetch_sub(old->memory_bytes(), std::memory_order_relaxed);
}

}  // namespace vox::pipeline
