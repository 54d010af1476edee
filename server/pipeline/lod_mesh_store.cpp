#include "server/pipeline/lod_mesh_store.hpp"

namespace vox::pipeline {

MeshVersionPtr LodMeshStore::get(const LodKey& k) const {
  std::lock_guard lock(mutex_);
  const auto it = meshes_.find(k);
  return it == meshes_.end() ? nullptr : it->second;
}

void LodMeshStore::publish(const LodKey& k, MeshVersionPtr mesh) {
  mesh->attach_account(delta_bytes_);
  const size_t bytes = mesh->memory_bytes();
  MeshVersionPtr old;  // released outside the lock
  {
    std::lock_guard lock(mutex_);
    auto [it, inserted] = meshes_.try_emplace(k);
    old = std::move(it->second);
    it->second = std::move(mesh);
    if (inserted) count_.fetch_add(1, std::memory_order_relaxed);
  }
  bytes_.fetch_add(bytes, std::memory_order_relaxed);
  if (old) bytes_.fetch_sub(old->memory_bytes(), std::memory_order_relaxed);
}

void LodMeshStore::erase(const LodKey& k) {
  MeshVersionPtr old;
  {
    std::lock_guard lock(mutex_);
    const auto it = meshes_.find(k);
    if (it == meshes_.end()) return;
    old = std::move(it->second);
    meshes_.erase(it);
    count_.fetch_sub(1, std::memory_order_relaxed);
  }
  bytes_.fetch_sub(old->memory_bytes(), std::memory_order_relaxed);
}

}  // namespace vox::pipeline
