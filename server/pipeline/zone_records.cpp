#include "server/pipeline/zone_records.hpp"

#include <spdlog/spdlog.h>

#include <optional>

#include "server/pipeline/memory_keeper.hpp"
#include "server/world/edit_apply.hpp"

namespace vox::pipeline {

AppliedRecords apply_zone_records(EditWorld& world, const ZoneRecords& records,
                                  Clock::time_point now) {
  AppliedRecords out;
  out.through = records.edits.empty() ? records.through : records.edits.front().seq - 1;
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

}  // namespace vox::pipeline
