// The pipeline's side of its group commit (DurableCommit keeps the rest): waiting a
// little for a batch's append after its re-mesh, and the region table's repair after a
// failed append.
#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

void WorldPipeline::repair_regions(Clock::time_point now, bool now_anyway) {
  if (!regions_.doubtful() || !commit_ || !commit_->empty()) return;
  if (!now_anyway && commit_->resting(now)) return;
  EditBatch b;  // no tasks: the append carries the region table (and forgets doubtful edits)
  commit_->start(b, regions_.write_for_append(b.regions));
  commit_->add(std::move(b));
}

void WorldPipeline::wait_for_answer(Clock::time_point until) {
  // Each pending batch is answered as soon as its append lands (oldest first), not when
  // the newest's does.
  while (!commit_->empty()) {
    const Clock::time_point start = Clock::now();
    bool go_on = false;  // an edit arrived, or the pipeline stops
    inbox_.wait_until(until, [&](const Inbox::State& in) {
      go_on = in.stopping || in.scheduler.has_ordered();
      return go_on || commit_->oldest_landed();
    });
    commit_->waited_for_oldest(seconds_since(start));
    if (!commit_->oldest_landed()) break;  // the wait is over, or an edit arrived
    commit_->finish(SIZE_MAX);             // every batch whose append has landed
    if (go_on) break;
  }
  commit_->finish(kMaxPendingBatches);
}

MeshVersionPtr WorldPipeline::newest_mesh(world::ChunkCoord c) const {
  if (commit_) {
    if (MeshVersionPtr pending = commit_->newest_mesh(c)) return pending;
  }
  return meshes_.get(c);
}

}  // namespace vox::pipeline
