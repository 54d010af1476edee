// What a game server asks of the world's samples (docs/PROTOCOL.md 4.13): where a ray first
// meets the surface, and the samples of a box. The surface is the one the mesher draws:
// a cell's triangles from the published case table, their vertices placed and shaded by
// edge_vertex() (fractions rounded to the wire's step), so a hit lies on the triangles a
// client renders. Pure functions over a ChunkSource, which may load what is asked of it or
// give up (then the query stops there, incomplete).
#pragma once

#include <string>
#include <vector>

#include "server/mesh/chunk_mesh.hpp"
#include "server/world/chunk_map.hpp"
#include "server/world/edit.hpp"

namespace vox::mesh {

// Where the samples come from: the chunk at c, or null when it cannot be had now (the
// query stops). A chunk is looked up again whenever the reader moves to another.
class ChunkSource {
 public:
  virtual ~ChunkSource() = default;
  virtual const world::Chunk* chunk(world::ChunkCoord c) = 0;
};

// The chunks of a map; a chunk not in it is open air.
class ChunkMapSource final : public ChunkSource {
 public:
  explicit ChunkMapSource(const world::ChunkMap& chunks) : chunks_(chunks) {}
  const world::Chunk* chunk(world::ChunkCoord c) override {
    const world::Chunk* found = chunks_.find(c);
    return found ? found : &air_;
  }

 private:
  const world::ChunkMap& chunks_;
  const world::Chunk air_;
};

struct Ray {
  world::Vec3 origin;
  world::Vec3 direction;  // unit length
  float max_distance = 0;
};

struct RayHit {
  bool hit = false;
  Vec3f point;
  Vec3f normal;  // unit, towards air: the vertex normals interpolated at the point
  world::Material material = world::kAir;  // the nearest vertex's
  float distance = 0;
  // False: the source gave up on a chunk the ray reached before any hit (`distance`: how
  // far along the ray the search got).
  bool complete = true;
};

// The first point of the surface along the ray within its max_distance, entering the
// surface from either side. Reads the cells along the ray and the samples their vertices'
// gradients reach, nearest first.
RayHit raycast(ChunkSource& chunks, const Ray& ray);

// The samples of `box` (inclusive), x fastest: densities as little-endian int16, materials
// one byte each; both strings resized to fit. False: the source gave up on a chunk.
bool read_samples(ChunkSource& chunks, const world::VoxelBox& box, std::string& densities,
                  std::string& materials);

}  // namespace vox::mesh
