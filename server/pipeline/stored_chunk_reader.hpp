// Reads checkpointed chunks back from the world store for every part of the pipeline that
// needs one (a load pass, an edit, the level-of-detail stage), with one failure state: a
// failed read is logged (then at most every 10 s while reads keep failing), and readers
// that back off wait until retry_at(). A read that works ends the failure. Pipeline
// thread only.
#pragma once

#include <chrono>
#include <functional>
#include <string>

#include "server/store/world_store.hpp"
#include "server/world/chunk.hpp"
#include "server/world/chunk_coord.hpp"

namespace vox::pipeline {

struct WorldState;

class StoredChunkReader {
 public:
  using Clock = std::chrono::steady_clock;
  // `before_read` runs before each read (the pipeline waits there for its appends: they
  // share the store's connection). `store` must outlive the reader.
  StoredChunkReader(store::WorldStore& store, std::chrono::milliseconds retry,
                    std::function<void()> before_read);

  // The chunk as stored. Throws store::StoreError (unreadable, missing, does not decode),
  // noted as a failure first.
  world::Chunk read(world::ChunkCoord c);
  // Loads stored chunk c into `state` (WorldState::load_stored, which reads through here);
  // false when the store failed.
  bool try_load(WorldState& state, world::ChunkCoord c, Clock::time_point now);

  bool failing() const { return failing_; }
  // While failing: readers that back off do not read before this.
  bool backing_off(Clock::time_point now) const { return failing_ && now < retry_at_; }
  Clock::time_point retry_at() const { return retry_at_; }
  const std::string& last_error() const { return last_error_; }

 private:
  void note_failure(const std::string& error);

  store::WorldStore& store_;
  const std::chrono::milliseconds retry_;
  const std::function<void()> before_read_;
  bool failing_ = false;
  std::string last_error_;
  Clock::time_point retry_at_{};
  Clock::time_point logged_at_{};
};

}  // namespace vox::pipeline
