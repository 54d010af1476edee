#include "server/pipeline/stored_chunk_reader.hpp"

#include <spdlog/spdlog.h>

#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"

namespace vox::pipeline {

namespace {
// A view resting on an unreadable chunk asks for it every pass: one line per this long.
constexpr auto kLogEvery = std::chrono::seconds(10);
}  // namespace

StoredChunkReader::StoredChunkReader(store::WorldStore& store, std::chrono::milliseconds retry,
                                     std::function<void()> before_read)
    : store_(store), retry_(retry), before_read_(std::move(before_read)) {}

world::Chunk StoredChunkReader::read(world::ChunkCoord c) {
  if (before_read_) before_read_();
  std::string why = "missing from the store";
  try {
    const auto record = store_.read_chunk(c);
    auto chunk = record ? store::decode_chunk(record->samples, &why) : std::nullopt;
    if (chunk) {
      failing_ = false;
      return std::move(*chunk);
    }
  } catch (const std::exception& e) {  // the store's own, or its driver's
    why = e.what();
  }
  const std::string error =
      fmt::format("{}: chunk ({}, {}, {}): {}", store_.name(), c.x, c.y, c.z, why);
  note_failure(error);
  throw store::StoreError(error);
}

bool StoredChunkReader::try_load(WorldState& state, world::ChunkCoord c, Clock::time_point now) {
  try {
    state.load_stored(c, now);
    return true;
  } catch (const store::StoreError&) {  // noted by read()
    return false;
  }
}

void StoredChunkReader::note_failure(const std::string& error) {
  const Clock::time_point now = Clock::now();
  last_error_ = error;
  retry_at_ = now + retry_;
  if (!failing_ || now - logged_at_ >= kLogEvery) {
    logged_at_ = now;
    spdlog::error("world store: {}; what needs the chunk waits until it can be read", error);
  }
  failing_ = true;
}

}  // namespace vox::pipeline
