// A 32^3 block of samples. A chunk whose samples are all equal is stored as that one
// sample (no arrays); any other chunk holds 32^3 int16 densities and 32^3 uint8 materials
// (96 KiB). Index of (x, y, z) is x + 32 * (y + 32 * z).
#pragma once

#include <cstddef>
#include <memory>

#include "server/world/chunk_coord.hpp"
#include "server/world/sample.hpp"

namespace vox::world {

class Chunk {
 public:
  Chunk() = default;  // uniform air
  explicit Chunk(Sample uniform) : uniform_(uniform) {}
  Chunk(const Chunk& other);
  Chunk& operator=(const Chunk& other);
  Chunk(Chunk&&) noexcept = default;
  Chunk& operator=(Chunk&&) noexcept = default;

  static constexpr int index(int x, int y, int z) { return x + kChunkSize * (y + kChunkSize * z); }

  bool is_uniform() const { return density_ == nullptr; }
  Sample uniform_value() const { return uniform_; }  // meaningful only when uniform
  Sample at(int x, int y, int z) const;
  Sample at(int i) const;

  // Write access; turns a uniform chunk into a full one first.
  void set(int x, int y, int z, Sample s);
  Density* densities();   // full arrays (expands a uniform chunk)
  Material* materials();  // full arrays (expands a uniform chunk)
  const Density* densities() const { return density_.get(); }    // null when uniform
  const Material* materials() const { return material_.get(); }  // null when uniform

  // Drops the arrays when every sample is equal. Returns true if the chunk is now uniform.
  bool compact();

  size_t memory_bytes() const;
  friend bool operator==(const Chunk& a, const Chunk& b);

 private:
  void expand();

  std::unique_ptr<Density[]> density_;
  std::unique_ptr<Material[]> material_;
  Sample uniform_{};
};

}  // namespace vox::world
