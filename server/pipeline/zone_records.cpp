#include "server/pipeline/zone_records.hpp"

#include <spdlog/spdlog.h>

#include <optional>
#include <unordered_set>

#include "server/pipeline/checkpoints.hpp"
#include "server/pipeline/memory_keeper.hpp"
#include "server/pipeline/protected_regions.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::pipeline {

namespace {

world::VoxelBox voxels_of(world::ChunkCoord c) {
  const int32_t n = world::kChunkSize;
  return {{c.x * n, c.y * n, c.z * n}, {c.x * n + n - 1, c.y * n + n - 1, c.z * n + n - 1}};
}

world::ChangedBox whole_chunk() {
  world::ChangedBox all;
  all.add(0, 0, 0);
  all.add(world::kChunkSize - 1, world::kChunkSize - 1, world::kChunkSize - 1);
  return all;
}

// The zone's checkpoint replaces the world's copies of its chunks (a chunk a checkpoint in
// flight holds is preserved first). False when one does not decode (nothing installed).
bool install_checkpoint(EditWorld& world, const store::ZoneCheckpoint& cp, Clock::time_point now,
                        AppliedRecords& out) {
  std::vector<world::Chunk> chunks;
  chunks.reserve(cp.chunks.size());
  for (const store::ChunkRecord& r : cp.chunks) {
    if (world.zone_chunks > 0 && world::zone_of(r.coord, world.zone_chunks) != cp.zone) {
      spdlog::error("zone ({}, {}): its checkpoint holds chunk ({}, {}, {}) of another zone",
                    cp.zone.x, cp.zone.z, r.coord.x, r.coord.y, r.coord.z);
      return false;
    }
    std::string error;
    std::optional<world::Chunk> chunk = store::decode_chunk(r.samples, &error);
    if (!chunk) {
      spdlog::error("zone ({}, {}): the checkpoint's chunk ({}, {}, {}) does not decode ({})",
                    cp.zone.x, cp.zone.z, r.coord.x, r.coord.y, r.coord.z, error);
      return false;
    }
    chunks.push_back(std::move(*chunk));
  }
  WorldState& st = world.state;
  const world::ChangedBox all = whole_chunk();
  std::vector<world::ChunkCoord> dirty;
  for (size_t i = 0; i < chunks.size(); ++i) {
    const world::ChunkCoord c = cp.chunks[i].coord;
    WorldState::ChunkInfo& info = st.info[c];
    if (const world::Chunk* live = st.chunks.find(c);
        live && info.checkpointing && world.checkpoints)
      world.checkpoints->preserve(c, *live);
    st.chunks.insert(c, std::move(chunks[i]));
    st.modified_count += info.modified ? 0 : 1;
    info.modified = info.unsaved = true;
    info.last_used = now;
    if (world.checkpoints) world.checkpoints->changed(c);
    world::append_dirty_chunks(c, all, dirty);
    out.touched.push_back(voxels_of(c));
  }
  for (const world::ChunkCoord& c : dirty) {
    if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
      out.batch.dirty.push_back(c);
      out.batch.edited_at.try_emplace(c, now);
    }
  }
  out.batch.any_edit = out.batch.any_edit || !chunks.empty();
  return true;
}

// The world forgets what it has of the zone (docs/CLUSTER.md, "Evicting a zone's
// chunks"): its changed chunks leave memory, none is read back from the store any more,
// and later loads generate them. One a view, a waiting mesh, the checkpoint in flight or a
// neighbour's mesh needs goes back to the generated terrain in place instead (re-meshed
// with its neighbours). Those `cp` lists are left to its install, which replaces them.
void forget_zone(EditWorld& world, world::ZoneId zone, const store::ZoneCheckpoint* cp,
                 Clock::time_point now, AppliedRecords& out) {
  WorldState& st = world.state;
  std::unordered_set<world::ChunkCoord, world::ChunkCoordHash> listed;
  if (cp) {
    for (const store::ChunkRecord& r : cp->chunks) listed.insert(r.coord);
  }
  const auto in_zone = [&](world::ChunkCoord c) {
    return world.zone_chunks > 0 && world::zone_of(c, world.zone_chunks) == zone;
  };
  const auto needed = [&](world::ChunkCoord c, const WorldState::ChunkInfo& info) {
    if (info.checkpointing || st.views.viewed(c) || st.pins.count(c)) return true;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto n = st.info.find(c.offset(dx, dy, dz));
          if ((dx | dy | dz) != 0 && n != st.info.end() && n->second.meshed) return true;
        }
    return false;
  };
  std::erase_if(st.stored, in_zone);
  const world::ChangedBox all = whole_chunk();
  std::vector<world::ChunkCoord> dirty;
  size_t reverted = 0, dropped = 0;
  for (auto it = st.info.begin(); it != st.info.end();) {
    const world::ChunkCoord c = it->first;
    WorldState::ChunkInfo& info = it->second;
    if (!info.modified || !in_zone(c) || listed.count(c)) {
      ++it;
      continue;
    }
    --st.modified_count;
    if (!needed(c, info)) {
      st.chunks.erase(c);
      world.meshes.erase(c);
      if (world.checkpoints) world.checkpoints->saved_again(c);  // no checkpoint looks for it
      it = st.info.erase(it);
      out.touched.push_back(voxels_of(c));  // coarse levels built from it
      ++dropped;
      continue;
    }
    ++it;
    if (const world::Chunk* live = st.chunks.find(c);
        live && info.checkpointing && world.checkpoints)
      world.checkpoints->preserve(c, *live);
    st.chunks.insert(c, world.generator.generate(c));
    info.modified = false;
    info.last_used = now;
    info.unsaved = false;  // generated terrain needs no saving (it may be evicted)
    if (world.checkpoints && info.checkpointing) world.checkpoints->forget(c);
    if (world.checkpoints && !info.checkpointing) world.checkpoints->saved_again(c);
    world::append_dirty_chunks(c, all, dirty);
    out.touched.push_back(voxels_of(c));
    ++reverted;
  }
  for (const world::ChunkCoord& c : dirty) {
    if (auto it = st.info.find(c); it != st.info.end() && it->second.meshed) {
      out.batch.dirty.push_back(c);
      out.batch.edited_at.try_emplace(c, now);
    }
  }
  out.batch.any_edit = out.batch.any_edit || reverted > 0;
  spdlog::info(
      "zone ({}, {}) forgotten (neither held nor followed, or lost after an eviction): {} "
      "changed chunks left memory, {} went back to the generated terrain; installed afresh "
      "from its checkpoint and log when followed or taken",
      zone.x, zone.z, dropped, reverted);
}

}  // namespace

AppliedRecords apply_zone_records(EditWorld& world, const ZoneRecords& records,
                                  Clock::time_point now) {
  AppliedRecords out;
  const store::ZoneCheckpoint* cp = records.checkpoint ? &*records.checkpoint : nullptr;
  if (records.fresh) forget_zone(world, records.zone, cp, now, out);
  out.through = records.edits.empty() ? records.through : records.edits.front().seq - 1;
  if (records.checkpoint) {
    out.through = 0;  // short of the checkpoint: nothing applied
    if (!install_checkpoint(world, *records.checkpoint, now, out)) {
      if (records.fresh) forget_zone(world, records.zone, nullptr, now, out);  // those too
      return out;
    }
    out.through = records.edits.empty() ? records.through : records.checkpoint->seq;
  }
  world.memory.new_batch();
  for (const store::LoggedEdit& e : records.edits) {
    std::vector<world::ChunkCoord> dirtied;
    EditResult result;
    const world::RefusalReason refused =
        apply_edit_step(world, e.edit, now, SIZE_MAX, dirtied, result, nullptr, e.keep);
    if (refused != world::RefusalReason::kNone) {
      spdlog::warn("zone ({}, {}): record {} cannot be applied now ({}); tried again later",
                   records.zone.x, records.zone.z, e.seq, world::to_string(refused));
      return out;
    }
    out.batch.any_edit = true;
    out.batch.counts.chunks_generated += result.chunks_generated;
    out.batch.dirty.insert(out.batch.dirty.end(), dirtied.begin(), dirtied.end());
    for (const world::ChunkCoord& c : dirtied) out.batch.edited_at.try_emplace(c, now);
    out.touched.push_back(world::touched_box(e.edit));
    out.through = e.seq;
  }
  out.through = records.through;
  return out;
}

void zone_records_turn(ZoneAuthority& zones, EditWorld world, Clock::time_point now,
                       const std::function<void(AppliedRecords&)>& publish) {
  static Clock::time_point logged_at{};  // pipeline thread only
  for (int reads = 0; reads < 4; ++reads) {
    std::optional<ZoneRecords> records;
    try {
      records = zones.next_records();
    } catch (const store::StoreError& e) {
      if (now - logged_at >= std::chrono::seconds(10)) {
        logged_at = now;
        spdlog::warn("zones: {} (a zone's log is read again shortly)", e.what());
      }
      return;
    }
    if (!records) return;
    AppliedRecords out = apply_zone_records(world, *records, now);
    publish(out);
    zones.applied(*records, out.through);
    if (out.through < records->through) return;
  }
}

void take_zone_regions(ZoneAuthority& zones, ProtectedRegions& regions, Clock::time_point now) {
  static Clock::time_point logged_at{};  // pipeline thread only
  try {
    std::optional<store::RegionTable> table = zones.take_regions();
    if (!table) return;
    spdlog::info("zones: the protected regions changed: {} in force", table->regions.size());
    regions.restore(std::move(*table));
  } catch (const store::StoreError& e) {
    if (now - logged_at >= std::chrono::seconds(10)) {
      logged_at = now;
      spdlog::warn("zones: {} (the protected regions are read again shortly)", e.what());
    }
  }
}

}  // namespace vox::pipeline
