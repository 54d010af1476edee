// Generates terrain chunks for view loads on background threads at a lower CPU priority,
// so that a batch of the pipeline installs ready chunks instead of generating them: edits
// never wait behind terrain generation (most of a load pass's time). Generation is a pure
// function of the seed, so a chunk generated here and one the pipeline generated itself
// meanwhile (for an edit) are equal; the pipeline keeps whichever came first.
//
// Bounded: at most `max_chunks` chunks queued, being generated or ready at once; the
// pipeline generates what it could not queue itself. The pipeline is the one owner of
// what it asked for: it takes every ready chunk each batch (take_ready).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <span>
#include <thread>
#include <unordered_set>
#include <utility>
#include <vector>

#include "server/world/terrain_generator.hpp"

namespace vox::pipeline {

class TerrainPrefetcher {
 public:
  // `on_ready` runs on a background thread after chunks became ready (no lock held); it
  // must not block. threads = 0: none (every request is refused: generate inline).
  // `reserve_bytes`: what a chunk not generated yet counts in memory_bytes() (its worst
  // case), so a memory budget sees terrain on its way.
  TerrainPrefetcher(const world::TerrainGenerator& generator, int threads, size_t max_chunks,
                    size_t reserve_bytes, std::function<void()> on_ready);
  ~TerrainPrefetcher();  // stops and joins; queued work is dropped
  TerrainPrefetcher(const TerrainPrefetcher&) = delete;
  TerrainPrefetcher& operator=(const TerrainPrefetcher&) = delete;

  // Pipeline thread. Queues the chunks of `coords` not already pending, while the bound
  // allows; returns those it could not take (the caller generates them).
  std::vector<world::ChunkCoord> request(std::span<const world::ChunkCoord> coords);
  // Pipeline thread: chunks generated since the last call, with their coordinates.
  std::vector<std::pair<world::ChunkCoord, world::Chunk>> take_ready();
  // Any thread.
  bool pending(world::ChunkCoord c) const;  // queued, being generated or ready
  size_t pending_count() const;
  size_t memory_bytes() const;  // the ready chunks', and reserve_bytes per chunk on its way

 private:
  struct Column {
    int32_t x, z;
    std::vector<int32_t> ys;
  };
  void work();

  const world::TerrainGenerator& generator_;
  const size_t max_chunks_, reserve_bytes_;
  const std::function<void()> on_ready_;
  mutable std::mutex mutex_;  // leaf lock: generation and on_ready run outside it
  std::condition_variable cv_;
  bool stopping_ = false;
  std::deque<Column> queue_;
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> pending_;
  std::vector<std::pair<world::ChunkCoord, world::Chunk>> ready_;
  size_t ready_bytes_ = 0;
  std::vector<std::thread> threads_;
};

}  // namespace vox::pipeline
