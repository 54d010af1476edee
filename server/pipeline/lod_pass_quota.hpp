// How one pass of the level-of-detail stage (lod_stage.hpp) shares its `max_chunks`
// between chunks to re-mesh and missing meshes: half each when both wait (a storm that
// keeps re-meshes due must not keep a new layout from being meshed), and at least one
// missing mesh even behind a backlog of chunks the store put off; and while a player
// waits for its first view, re-meshes only every kFirstViewRemeshTurn-th pass. Pure; any
// thread.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace vox::pipeline {

// While some player still waits for its first view (it sees nothing until every mesh of
// its layout came), a pass takes re-meshes only once in this many: a re-mesh is a chunk
// with every seams variant wanted (often 5 to 10 meshes), which in half of every pass
// kept a crowd's first views waiting behind the coarse chunks its edits had changed.
inline constexpr uint64_t kFirstViewRemeshTurn = 8;

// Whether pass number `pass` may take re-meshes.
constexpr bool lod_remesh_turn(bool first_views_wait, uint64_t pass) {
  return !first_views_wait || pass % kFirstViewRemeshTurn == 0;
}

// Due re-meshes to take, when `retried` chunks put off by the store go first.
constexpr size_t lod_remesh_quota(size_t max_chunks, size_t retried, bool missing) {
  const size_t quota = missing ? std::max<size_t>(1, max_chunks / 2) : max_chunks;
  return retried < quota ? quota - retried : 0;
}

// Missing meshes to take once `chunks` chunks (retried and re-meshed) are in the pass.
constexpr size_t lod_missing_quota(size_t max_chunks, size_t chunks, bool missing) {
  if (!missing) return 0;
  return std::max<size_t>(1, chunks < max_chunks ? max_chunks - chunks : 0);
}

}  // namespace vox::pipeline
