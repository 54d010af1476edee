// The pipeline's durable side (PipelineConfig::store): restoring the world at start,
// reading checkpointed chunks back, and undoing a batch the store refused. Appending the
// batches is in world_pipeline_commit.cpp, the batch loop in world_pipeline.cpp.
#include <spdlog/spdlog.h>

#include <future>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

// The world as the store has it: the checkpointed chunks (read when first needed), then
// the log after the checkpoint applied in order, exactly as the batches applied it (so the
// densities are bit-identical). The chunks the replay changed are unsaved: the next
// checkpoint writes them.
void WorldPipeline::restore_from_store() {
  store::WorldStore& store = *config_.store;
  WorldState& st = *state_;
  const Clock::time_point start = Clock::now();
  const store::WorldInfo info = store.info();
  store.for_each_chunk([&st](ChunkCoord c, uint64_t) { st.stored.insert(c); });
  regions_.restore(store.read_regions());
  // The log's tail is bounded by the checkpoints (CheckpointLimits::max_unsaved_edits, plus
  // what one interval accepts).
  std::vector<store::LoggedEdit> tail;
  store.for_each_edit(info.checkpoint_seq, [&tail](const store::LoggedEdit& e) {
    tail.push_back(e);
    return true;
  });
  preload_stored(tail);
  uint64_t replayed = 0, last = info.checkpoint_seq;
  EditWorld world_access = edit_world();
  for (const store::LoggedEdit& e : tail) {
    std::vector<ChunkCoord> dirtied;  // nothing is meshed yet
    EditResult ignored;
    const auto refused =
        apply_edit_step(world_access, e.edit, start, SIZE_MAX, dirtied, ignored, nullptr, e.keep);
    if (refused == world::RefusalReason::kStorageUnavailable) {
      throw store::StoreError(fmt::format("{}: replaying edit {}: a checkpointed chunk: {}",
                                          store.name(), e.seq, reader_->last_error()));
    }
    if (refused != world::RefusalReason::kNone) {
      throw store::StoreError(fmt::format(
          "{}: logged edit {} cannot be applied again ({}); is --max-memory smaller than the "
          "world?",
          store.name(), e.seq, world::to_string(refused)));
    }
    ++replayed;
    last = e.seq;
  }
  commit_->restore(std::max(info.last_seq, last) + 1);
  checkpoints_->logged(replayed);
  stats_.modified_chunks = st.modified_count;
  stats_.loaded_chunks = st.chunks.size();
  stats_.chunk_bytes = st.chunks.memory_bytes();
  stats_.stored_chunks = st.stored.size();
  stats_.unsaved_chunks = checkpoints_->unsaved_chunks();
  stats_.checkpoint_seq = info.checkpoint_seq;
  spdlog::info(
      "world: {} (seed {}, start {}): {} stored chunks, {} protected regions, {} logged edits "
      "replayed in {:.0f} ms",
      store.name(), info.seed, info.starts, st.stored.size(), regions_.in_force().size(), replayed,
      seconds_since(start) * 1000);
}

// The chunks the log's tail touches or reads, loaded before it is replayed: the stored ones
// read in one go and decompressed in parallel, the others generated in parallel (one at a
// time as the replay met them, a restart spent most of its time here).
void WorldPipeline::preload_stored(const std::vector<store::LoggedEdit>& tail) {
  WorldState& st = *state_;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> wanted;
  std::vector<ChunkCoord> to_generate;
  for (const store::LoggedEdit& e : tail) {
    const auto* smooth = std::get_if<world::Smooth>(&e.edit);
    for (const ChunkCoord& c : world::chunks_overlapping(smooth ? world::smooth_read_box(*smooth)
                                                                : world::touched_box(e.edit))) {
      if (st.stored.count(c)) {
        wanted.insert(c);
      } else {
        to_generate.push_back(c);
      }
    }
  }
  std::vector<ChunkCoord> coords(wanted.begin(), wanted.end());
  std::vector<std::vector<uint8_t>> bytes(coords.size());
  for (size_t i = 0; i < coords.size(); ++i) {
    auto record = config_.store->read_chunk(coords[i]);
    if (record) bytes[i] = std::move(record->samples);
  }
  std::vector<std::optional<world::Chunk>> chunks(coords.size());
  std::vector<std::string> why(coords.size());
  parallel_for_index(st.arena, coords.size(),
                     [&](size_t i) { chunks[i] = store::decode_chunk(bytes[i], &why[i]); });
  const Clock::time_point now = Clock::now();
  for (size_t i = 0; i < coords.size(); ++i) {
    const ChunkCoord c = coords[i];
    if (!chunks[i]) {
      throw store::StoreError(
          fmt::format("{}: chunk ({}, {}, {}): {}", config_.store->name(), c.x, c.y, c.z, why[i]));
    }
    st.chunks.insert(c, std::move(*chunks[i]));
    st.info[c] = {.modified = true, .last_used = now};
    ++st.modified_count;
  }
  st.ensure_loaded(to_generate, generator_, now);  // duplicates are skipped
}

// Undoes the batch's edits, last first: each chunk gets back its samples and its flags
// as they were before the batch (a chunk an edit compacted to one sample is expanded
// again; the samples outside the box were that sample already).
void WorldPipeline::roll_back(Undo& undo) {
  WorldState& st = *state_;
  for (auto it = undo.patches.rbegin(); it != undo.patches.rend(); ++it) {
    const Undo::Patch& p = *it;
    world::Chunk* chunk = st.chunks.find(p.coord);
    if (!chunk) continue;  // cannot happen: a batch evicts nothing it touched
    WorldState::ChunkInfo& info = st.info.at(p.coord);
    if (info.checkpointing) checkpoints_->preserve(p.coord, *chunk);  // preserved already
    const bool was_uniform = chunk->is_uniform();
    if (p.was_uniform) {
      *chunk = world::Chunk(p.uniform);
    } else {
      size_t i = 0;
      for (int z = p.lo[2]; z <= p.hi[2]; ++z)
        for (int y = p.lo[1]; y <= p.hi[1]; ++y)
          for (int x = p.lo[0]; x <= p.hi[0]; ++x) chunk->set(x, y, z, p.samples[i++]);
    }
    st.chunks.note_changed(was_uniform, *chunk);
    if (info.modified && !p.modified) --st.modified_count;
    info.modified = p.modified;
    info.unsaved = p.unsaved;
    if (!p.unsaved) checkpoints_->saved_again(p.coord);
  }
  undo.patches.clear();
}

}  // namespace vox::pipeline
