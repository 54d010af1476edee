// The pipeline's durable side (PipelineConfig::store): restoring the world at start,
// appending each batch's edits while it re-meshes, and undoing a batch the store refused.
// The batch loop itself is in world_pipeline.cpp.
#include <spdlog/spdlog.h>

#include <future>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

// The world as the store has it: every checkpointed chunk, then the log after the
// checkpoint applied in order, exactly as the batches applied it (so the densities are
// bit-identical). Eager: the chunks are resident from the start (modified chunks are
// never evicted).
void WorldPipeline::restore_from_store() {
  store::WorldStore& store = *config_.store;
  WorldState& st = *state_;
  const Clock::time_point start = Clock::now();
  const store::WorldInfo info = store.info();
  std::vector<ChunkCoord> coords;
  store.for_each_chunk([&coords](ChunkCoord c, uint64_t) { coords.push_back(c); });
  for (const ChunkCoord& c : coords) {
    const auto record = store.read_chunk(c);
    if (!record) continue;
    std::string why;
    auto chunk = store::decode_chunk(record->samples, &why);
    if (!chunk) {
      throw store::StoreError(
          fmt::format("{}: chunk ({}, {}, {}): {}", store.name(), c.x, c.y, c.z, why));
    }
    st.chunks.insert(c, std::move(*chunk));
    auto& i = st.info[c];
    i.modified = true;
    i.last_used = start;
    ++st.modified_count;
  }
  uint64_t replayed = 0, last = info.checkpoint_seq;
  store.for_each_edit(info.checkpoint_seq, [&](const store::LoggedEdit& e) {
    std::vector<ChunkCoord> dirtied;  // nothing is meshed yet
    EditResult ignored;
    const auto refused = apply_edit_task(e.edit, start, SIZE_MAX, dirtied, ignored);
    if (refused != world::RefusalReason::kNone) {
      throw store::StoreError(fmt::format(
          "{}: logged edit {} cannot be applied again ({}); is --max-memory smaller than the "
          "world?",
          store.name(), e.seq, world::to_string(refused)));
    }
    ++replayed;
    last = e.seq;
    return true;
  });
  next_seq_ = std::max(info.last_seq, last) + 1;
  stats_.modified_chunks = st.modified_count;
  stats_.loaded_chunks = st.chunks.size();
  stats_.chunk_bytes = st.chunks.memory_bytes();
  spdlog::info(
      "world: {} (seed {}, start {}): {} stored chunks, {} logged edits replayed in {:.0f} ms",
      store.name(), info.seed, info.starts, coords.size(), replayed, seconds_since(start) * 1000);
}

std::string WorldPipeline::commit_while(const std::vector<const world::Edit*>& accepted,
                                        const std::function<void()>& work) {
  const int64_t unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count();
  std::vector<store::LoggedEdit> log;
  log.reserve(accepted.size());
  // Sequence numbers are never reused, even after a failed append (its outcome may be in
  // doubt): the log may have gaps, never two edits with one number.
  for (const world::Edit* e : accepted) log.push_back({next_seq_++, unix_ms, "", *e});
  store::WorldStore& store = *config_.store;
  const Clock::time_point start = Clock::now();
  double commit_s = 0;
  auto append = std::async(std::launch::async, [&store, &log, &commit_s, start]() -> std::string {
    std::string error;
    try {
      store.append_edits(log);
    } catch (const std::exception& e) {
      error = e.what();
    }
    commit_s = seconds_since(start);
    return error;
  });
  work();
  const Clock::time_point worked = Clock::now();
  std::string error = append.get();
  if (observer_.commit) {
    observer_.commit(commit_s, std::chrono::duration<double>(Clock::now() - worked).count(),
                     log.size(), error.empty());
  }
  if (!error.empty()) {
    store_retry_at_ = Clock::now() + config_.store_retry;
    if (!store_failing_) spdlog::error("world store: {}; edits are refused until it works", error);
    store_failing_ = true;
  } else if (store_failing_) {
    store_failing_ = false;
    spdlog::info("world store: writing again; edits are accepted");
  }
  return error;
}

void WorldPipeline::roll_back(Undo& undo) {
  WorldState& st = *state_;
  for (auto& [coord, saved] : undo.chunks) {
    world::Chunk* chunk = st.chunks.find(coord);
    if (!chunk) continue;  // cannot happen: a batch evicts nothing it touched
    const bool was_uniform = chunk->is_uniform();
    *chunk = std::move(saved.first);
    st.chunks.note_changed(was_uniform, *chunk);
    bool& modified = st.info.at(coord).modified;
    if (modified && !saved.second) --st.modified_count;
    modified = saved.second;
  }
  undo.chunks.clear();
}

}  // namespace vox::pipeline
