#include "server/pipeline/world_restore.hpp"

#include <spdlog/spdlog.h>

#include <optional>
#include <unordered_set>

#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/world_history.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

// The chunks the log's tail touches or reads, loaded before it is replayed: the stored ones
// read in one go and decompressed in parallel, the others generated in parallel (one at a
// time as the replay met them, a restart spent most of its time here).
void preload(store::WorldStore& store, EditWorld& w, const std::vector<store::LoggedEdit>& tail) {
  WorldState& st = w.state;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> wanted;
  std::vector<ChunkCoord> to_generate;
  for (const store::LoggedEdit& e : tail) {
    if (e.undoes) continue;  // a rollback record recomputes its chunks itself
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
    auto record = store.read_chunk(coords[i]);
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
          fmt::format("{}: chunk ({}, {}, {}): {}", store.name(), c.x, c.y, c.z, why[i]));
    }
    st.chunks.insert(c, std::move(*chunks[i]));
    st.info[c] = {.modified = true, .last_used = now};
    ++st.modified_count;
  }
  st.ensure_loaded(to_generate, w.generator, now);  // duplicates are skipped
}

}  // namespace

RestoredWorld restore_world(store::WorldStore& store, EditWorld& w, ProtectedRegions& regions,
                            const StoredChunkReader& reader) {
  WorldState& st = w.state;
  const Clock::time_point start = Clock::now();
  RestoredWorld out;
  out.info = store.info();
  store.for_each_chunk([&st](ChunkCoord c, uint64_t) { st.stored.insert(c); });
  regions.restore(store.read_regions());
  // The log's tail is bounded by the checkpoints (CheckpointLimits::max_unsaved_edits, plus
  // what one interval accepts).
  std::vector<store::LoggedEdit> tail;
  store.for_each_edit(out.info.checkpoint_seq, [&tail](const store::LoggedEdit& e) {
    tail.push_back(e);
    return true;
  });
  preload(store, w, tail);
  uint64_t last = out.info.checkpoint_seq;
  for (const store::LoggedEdit& e : tail) {
    if (e.undoes) {              // a rollback: its chunks as the history recomputes them
      if (!out.info.base_seq) {  // the base went with a trim of the whole log
        spdlog::error(
            "world: rollback {} is logged but the history it needs was trimmed (--history-days "
            "0); it is not replayed: its edits stay",
            e.seq);
        last = e.seq;
        continue;
      }
      for (auto& [c, chunk] : store::replay_rollback(store, w.generator, e, w.zone_chunks))
        replace_chunk(w, c, std::move(chunk), start);
      ++out.rollbacks;
      last = e.seq;
      continue;
    }
    std::vector<ChunkCoord> dirtied;  // nothing is meshed yet
    EditResult ignored;
    const auto refused =
        apply_edit_step(w, e.edit, start, SIZE_MAX, dirtied, ignored, nullptr, e.keep);
    if (refused == world::RefusalReason::kStorageUnavailable) {
      throw store::StoreError(fmt::format("{}: replaying edit {}: a checkpointed chunk: {}",
                                          store.name(), e.seq, reader.last_error()));
    }
    if (refused != world::RefusalReason::kNone) {
      throw store::StoreError(fmt::format(
          "{}: logged edit {} cannot be applied again ({}); is --max-memory smaller than the "
          "world?",
          store.name(), e.seq, world::to_string(refused)));
    }
    ++out.replayed;
    last = e.seq;
  }
  out.next_seq = std::max(out.info.last_seq, last) + 1;
  spdlog::info(
      "world: {} (seed {}, start {}): {} stored chunks, {} protected regions, {} logged edits "
      "and {} rollbacks replayed in {:.0f} ms",
      store.name(), out.info.seed, out.info.starts, st.stored.size(), regions.in_force().size(),
      out.replayed, out.rollbacks, seconds_since(start) * 1000);
  return out;
}

}  // namespace vox::pipeline
