#include "server/world/chunk.hpp"

#include <algorithm>
#include <cstring>

namespace vox::world {

Chunk::Chunk(const Chunk& other) : uniform_(other.uniform_) {
  if (!other.is_uniform()) {
    density_ = std::make_unique_for_overwrite<Density[]>(kChunkVolume);
    material_ = std::make_unique_for_overwrite<Material[]>(kChunkVolume);
    std::memcpy(density_.get(), other.density_.get(), kChunkVolume * sizeof(Density));
    std::memcpy(material_.get(), other.material_.get(), kChunkVolume * sizeof(Material));
  }
}

Chunk& Chunk::operator=(const Chunk& other) {
  if (this != &other) *this = Chunk(other);
  return *this;
}

Sample Chunk::at(int i) const {
  if (is_uniform()) return uniform_;
  return {density_[i], material_[i]};
}

Sample Chunk::at(int x, int y, int z) const { return at(index(x, y, z)); }

void Chunk::expand() {
  if (!is_uniform()) return;
  density_ = std::make_unique_for_overwrite<Density[]>(kChunkVolume);
  material_ = std::make_unique_for_overwrite<Material[]>(kChunkVolume);
  std::fill_n(density_.get(), kChunkVolume, uniform_.density);
  std::fill_n(material_.get(), kChunkVolume, uniform_.material);
}

void Chunk::set(int x, int y, int z, Sample s) {
  if (is_uniform() && s == uniform_) return;
  expand();
  const int i = index(x, y, z);
  density_[i] = s.density;
  material_[i] = s.material;
}

Density* Chunk::densities() {
  expand();
  return density_.get();
}

Material* Chunk::materials() {
  expand();
  return material_.get();
}

bool Chunk::compact() {
  if (is_uniform()) return true;
  const Density d0 = density_[0];
  const Material m0 = material_[0];
  const bool same_density = std::all_of(density_.get(), density_.get() + kChunkVolume,
                                        [d0](Density d) { return d == d0; });
  if (!same_density) return false;
  const bool same_material = std::all_of(material_.get(), material_.get() + kChunkVolume,
                                         [m0](Material m) { return m == m0; });
  if (!same_material) return false;
  uniform_ = {d0, m0};
  density_.reset();
  material_.reset();
  return true;
}

size_t Chunk::memory_bytes() const {
  size_t bytes = sizeof(Chunk);
  if (!is_uniform()) bytes += kChunkVolume * (sizeof(Density) + sizeof(Material));
  return bytes;
}

bool operator==(const Chunk& a, const Chunk& b) {
  if (a.is_uniform() && b.is_uniform()) return a.uniform_ == b.uniform_;
  for (int i = 0; i < kChunkVolume; ++i) {
    if (a.at(i) != b.at(i)) return false;
  }
  return true;
}

}  // namespace vox::world
