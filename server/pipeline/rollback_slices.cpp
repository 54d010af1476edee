#include "server/pipeline/rollback_slices.hpp"

#include "server/pipeline/lod_stage.hpp"
#include "server/world/edit.hpp"

namespace vox::pipeline {

void RollbackSlices::answer(EditBatch& b, bool durable, LodStage& lod) {
  for (size_t t = 0; t < b.tasks.size(); ++t) {
    auto* slice = std::get_if<RollbackTask>(&b.tasks[t]);
    if (!slice || slice->kind != RollbackTask::Kind::kInstall) continue;
    const bool ok = durable && b.results[t].accepted;
    if (ok && slice->undoes && !slice->last) hold_checkpoints_ = true;  // more slices follow
    if (ok && slice->last) hold_checkpoints_ = false;
    if (ok) {
      const Clock::time_point now = Clock::now();
      for (const auto& [c, chunk] : slice->chunks) {
        frozen_.erase(c);
        lod.edited(world::chunk_box(c), now);
      }
    }
    if (slice->done) slice->done(ok, ok && slice->undoes ? b.seqs.first + b.record->before : 0);
  }
}

}  // namespace vox::pipeline
