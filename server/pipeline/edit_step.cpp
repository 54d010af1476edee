// Applying one edit to the world (edit_step.hpp): what the edit needs loaded, the memory
// budget's say, the undo record and the copy a checkpoint in flight needs, then the
// change itself over the touched chunks in parallel; and a batch of them undone. The
// batch around it is in world_pipeline.cpp.
#include "server/pipeline/edit_step.hpp"

#include <vector>

#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/world/edit_apply.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

world::RefusalReason load_chunks(EditWorld& w, const std::vector<ChunkCoord>& wanted,
                                 size_t max_generate, size_t may_expand, Clock::time_point now,
                                 size_t& generated) {
  WorldState& st = w.state;
  size_t missing = 0;
  for (const ChunkCoord& c : wanted) missing += st.info.count(c) ? 0 : 1;
  if (missing > max_generate) return world::RefusalReason::kOverBudget;
  // What is resident: terrain on its way for loads (reserved) does not hold edits back.
  const MemoryBudget& budget = w.memory.budget();
  if (!budget.may_generate(w.resident_bytes(), missing + may_expand)) {
    const size_t need = (missing + may_expand) * MemoryBudget::kBytesPerChunk;
    const auto pass = w.memory.for_edits(need, w.other_bytes);
    if (!pass) return world::RefusalReason::kServerBusy;  // made room once this batch already
    st.evict(w.meshes, now, pass->idle, pass->min_age, pass->target_bytes, pass->max_scan);
    if (!budget.may_generate(w.resident_bytes(), missing + may_expand))
      return world::RefusalReason::kServerBusy;
  }
  try {
    generated = st.ensure_loaded(wanted, w.generator, now);
  } catch (const store::StoreError&) {  // a checkpointed chunk could not be read back
    return world::RefusalReason::kStorageUnavailable;
  }
  return world::RefusalReason::kNone;
}

world::RefusalReason apply_edit_step(EditWorld& w, const world::Edit& edit, Clock::time_point now,
                                     size_t max_generate, std::vector<ChunkCoord>& dirtied,
                                     EditResult& result, Undo* undo,
                                     std::span<const world::VoxelBox> keep) {
  WorldState& st = w.state;
  const world::VoxelBox box = world::touched_box(edit);
  const std::vector<ChunkCoord> touched = world::chunks_overlapping(box);
  // What must be loaded: the touched chunks (and what a smooth reads), and every meshed
  // chunk the edit may dirty (the touched ones and their neighbours) with its neighbours,
  // to re-mesh it. Chunks no one has a mesh of are not re-meshed (a view that loads them
  // meshes them then), so an edit where nothing is meshed generates only what it touches.
  std::vector<ChunkCoord> wanted = touched;
  if (const auto* smooth = std::get_if<world::Smooth>(&edit)) {
    wanted = world::chunks_overlapping(world::smooth_read_box(*smooth));
  }
  // Neighbours of meshed chunks, marked in the box touched +-2 (no sort, no duplicates).
  const ChunkCoord lo = touched.front().offset(-2, -2, -2), hi = touched.back().offset(2, 2, 2);
  const int nx = hi.x - lo.x + 1, ny = hi.y - lo.y + 1, nz = hi.z - lo.z + 1;
  std::vector<char> marked(static_cast<size_t>(nx) * ny * nz, 0);
  auto index = [&](int32_t x, int32_t y, int32_t z) {
    return static_cast<size_t>(x - lo.x) +
           static_cast<size_t>(nx) * ((y - lo.y) + static_cast<size_t>(ny) * (z - lo.z));
  };
  for (const ChunkCoord& c : wanted) {
    if (c.x >= lo.x && c.x <= hi.x && c.y >= lo.y && c.y <= hi.y && c.z >= lo.z && c.z <= hi.z)
      marked[index(c.x, c.y, c.z)] = 1;  // already wanted
  }
  for (int32_t z = lo.z + 1; z < hi.z; ++z)
    for (int32_t y = lo.y + 1; y < hi.y; ++y)
      for (int32_t x = lo.x + 1; x < hi.x; ++x) {
        auto it = st.info.find({x, y, z});
        if (it == st.info.end() || !it->second.meshed) continue;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              char& m = marked[index(x + dx, y + dy, z + dz)];
              if (!m) wanted.push_back({x + dx, y + dy, z + dz});
              m = 1;
            }
      }
  size_t may_expand = 0;  // touched chunks that are (or may come out) uniform
  for (const ChunkCoord& c : touched) {
    const world::Chunk* chunk = st.chunks.find(c);
    may_expand += !chunk || chunk->is_uniform() ? 1 : 0;
  }
  if (const auto refused =
          load_chunks(w, wanted, max_generate, may_expand, now, result.chunks_generated);
      refused != world::RefusalReason::kNone)
    return refused;

  std::optional<world::SampleSnapshot> snapshot;
  if (const auto* smooth = std::get_if<world::Smooth>(&edit)) {
    snapshot = world::take_snapshot(st.chunks, world::smooth_read_box(*smooth));
    snapshot->zone_chunks = w.zone_chunks;
  }
  std::vector<world::ChangedBox> changed(touched.size());
  std::vector<ChunkCoord> dirty_here;  // chunks whose mesh reads a changed sample
  std::vector<world::Chunk*> targets(touched.size());
  std::vector<char> was_uniform(touched.size());
  for (size_t i = 0; i < touched.size(); ++i) {
    targets[i] = st.chunks.find(touched[i]);
    was_uniform[i] = targets[i]->is_uniform();
    const WorldState::ChunkInfo& i_info = st.info.at(touched[i]);
    // A checkpoint in flight still needs it as it is: the writer gets a copy.
    if (i_info.checkpointing) w.checkpoints->preserve(touched[i], *targets[i]);
    if (undo) undo->save(touched[i], *targets[i], box, i_info.modified, i_info.unsaved);
  }
  const world::SampleSnapshot* snap = snapshot ? &*snapshot : nullptr;
  std::vector<world::VolumeTally> tallies(touched.size());  // what each chunk gave and got
  if (touched.size() == 1) {
    changed[0] = world::apply_edit(edit, touched[0], *targets[0], snap, keep, &tallies[0]);
  } else {
    parallel_for_index(st.arena, touched.size(), [&](size_t i) {
      changed[i] = world::apply_edit(edit, touched[i], *targets[i], snap, keep, &tallies[i]);
    });
  }
  for (size_t i = 1; i < tallies.size(); ++i) tallies[0].merge(tallies[i]);
  result.volumes.clear();
  tallies[0].materials([&](const world::MaterialVolume& v) { result.volumes.push_back(v); });
  for (size_t i = 0; i < touched.size(); ++i) {
    st.chunks.note_changed(was_uniform[i] != 0, *targets[i]);
    result.chunks_expanded += was_uniform[i] && !targets[i]->is_uniform() ? 1 : 0;
    if (!changed[i].changed) continue;
    WorldState::ChunkInfo& info = st.info.at(touched[i]);
    st.modified_count += info.modified ? 0 : 1;
    info.modified = info.unsaved = true;
    if (w.checkpoints) w.checkpoints->changed(touched[i]);
    world::append_dirty_chunks(touched[i], changed[i], dirty_here);
  }
  for (const ChunkCoord& c : dirty_here) {
    if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) dirtied.push_back(c);
  }
  return world::RefusalReason::kNone;
}

void replace_chunk(EditWorld& w, ChunkCoord c, world::Chunk chunk, Clock::time_point now) {
  WorldState& st = w.state;
  WorldState::ChunkInfo& info = st.info[c];
  if (world::Chunk* old = st.chunks.find(c)) {
    if (info.checkpointing && w.checkpoints) w.checkpoints->preserve(c, *old);
    const bool was_uniform = old->is_uniform();
    *old = std::move(chunk);
    st.chunks.note_changed(was_uniform, *old);
  } else {
    st.chunks.insert(c, std::move(chunk));
  }
  st.modified_count += info.modified ? 0 : 1;
  info.modified = info.unsaved = true;
  info.last_used = now;
  if (w.checkpoints) w.checkpoints->changed(c);
}

world::RefusalReason install_chunks(EditWorld& w,
                                    std::vector<std::pair<world::ChunkCoord, world::Chunk>>& chunks,
                                    Clock::time_point now, std::vector<ChunkCoord>& dirtied,
                                    Undo* undo) {
  WorldState& st = w.state;
  std::vector<ChunkCoord> wanted;
  for (const auto& [c, chunk] : chunks) wanted.push_back(c);
  try {
    st.ensure_loaded(wanted, w.generator, now);
  } catch (const store::StoreError&) {
    return world::RefusalReason::kStorageUnavailable;
  }
  std::vector<ChunkCoord> dirty_here;
  for (auto& [c, chunk] : chunks) {
    const WorldState::ChunkInfo& info = st.info.at(c);
    const int32_t k = world::kChunkSize;
    const world::VoxelBox whole = world::chunk_box(c);
    const world::Chunk& old = *st.chunks.find(c);
    // Only the meshes reading samples that differ are rebuilt (a chunk's neighbours read
    // its faces; most of a rollback's changes lie inside).
    world::ChangedBox changed;
    for (int z = 0; z < k; ++z)
      for (int y = 0; y < k; ++y)
        for (int x = 0; x < k; ++x)
          if (!(old.at(x, y, z) == chunk.at(x, y, z))) changed.add(x, y, z);
    if (!changed.changed) continue;  // the same samples: nothing to put in place
    if (undo) undo->save(c, old, whole, info.modified, info.unsaved);
    replace_chunk(w, c, std::move(chunk), now);
    world::append_dirty_chunks(c, changed, dirty_here);
  }
  for (const ChunkCoord& c : dirty_here) {
    if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) dirtied.push_back(c);
  }
  return world::RefusalReason::kNone;
}

void undo_edits(WorldState& st, Checkpoints* checkpoints, Undo& undo) {
  for (auto it = undo.patches.rbegin(); it != undo.patches.rend(); ++it) {
    const Undo::Patch& p = *it;
    world::Chunk* chunk = st.chunks.find(p.coord);
    if (!chunk) continue;  // cannot happen: a batch evicts nothing it touched
    WorldState::ChunkInfo& info = st.info.at(p.coord);
    if (info.checkpointing && checkpoints) checkpoints->preserve(p.coord, *chunk);
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
    if (!p.unsaved && checkpoints) checkpoints->saved_again(p.coord);
  }
  undo.patches.clear();
}

}  // namespace vox::pipeline
