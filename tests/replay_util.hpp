// What the rollback tests compare against: the world of some players' edits alone, replayed
// onto the seed (world::replay_edit, bit for bit as the pipeline applies them).
#pragma once

#include <map>
#include <vector>

#include "server/world/chunk_map.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/edit_replay.hpp"

namespace vox::test {

// Every chunk any of `turns` reached, as the turns not by `skip` leave it (Turn has `who`
// and `edit`, any edit kind).
template <class Turn, class Who>
std::map<world::ChunkCoord, world::Chunk> replayed_without(const std::vector<Turn>& turns,
                                                           const Who& skip,
                                                           const world::TerrainGenerator& gen) {
  world::ChunkMap map;
  for (const Turn& t : turns)
    if (!(t.who == skip)) world::replay_edit(map, gen, world::Edit(t.edit));
  std::map<world::ChunkCoord, world::Chunk> out;
  for (const Turn& t : turns)
    for (const world::ChunkCoord& c :
         world::chunks_overlapping(world::touched_box(world::Edit(t.edit)))) {
      if (!map.find(c)) map.insert(c, gen.generate(c));
      out.emplace(c, *map.find(c));
    }
  return out;
}

}  // namespace vox::test
