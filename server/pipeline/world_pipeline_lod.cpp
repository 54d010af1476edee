// The pipeline's level-of-detail part: views set from any thread, taken
// between batches; a LodStage pass after each batch's loads; durable edits marked.
#include <spdlog/spdlog.h>

#include "server/pipeline/world_pipeline.hpp"
#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

// Pipeline thread. While a batch waits for the store, the chunk map may show edits that
// are not durable: no LOD mesh is made from it then (the append's landing wakes us).
bool WorldPipeline::lod_ready(const Inbox::State& in, Clock::time_point now) const {
  return !batches_in_flight() && (!in.lod_updates.empty() || lod_->has_work(now));
}

void WorldPipeline::lod_pass(Clock::time_point now) {
  std::unordered_map<LoadOwner, std::vector<LodKey>> updates;
  bool edits_waiting = false;
  inbox_.locked([&](Inbox::State& in) {
    updates.swap(in.lod_updates);
    edits_waiting = in.scheduler.has_ordered();
  });
  LodPublication late;                   // keys owners now want that were published before they did
  for (auto& [owner, keys] : updates) {  // outside the lock
    std::vector<LodKey> published = lod_->set_wants(owner, std::move(keys));
    if (!published.empty())
      late.by_owner.emplace_back(owner,
                                 std::make_shared<const std::vector<LodKey>>(std::move(published)));
  }
  if (!late.by_owner.empty()) subscribers_.notify_lod(late);
  if (!lod_->has_work(now)) {
    lod_starved_since_.reset();
    return;
  }
  if (batches_in_flight()) {
    // Edits keep a batch waiting for the store: after a while, wait for the appends so the
    // coarse levels do not starve.
    if (!lod_starved_since_) lod_starved_since_ = now;
    if (now - *lod_starved_since_ < kLodStarvation) return;
    finish_pending(0);
    if (batches_in_flight()) return;
  }
  lod_starved_since_.reset();
  const Clock::time_point start = Clock::now();
  for (;;) {
    notify_lod(lod_->run(Clock::now(), config_.lod_group_chunks));
    if (edits_waiting || Clock::now() - start >= config_.lod_pass_time ||
        !lod_->has_work(Clock::now()))
      return;
    const bool edit_or_stop = inbox_.locked(
        [](const Inbox::State& in) { return in.scheduler.has_ordered() || in.stopping; });
    if (edit_or_stop) return;  // an edit arrived: it goes first
  }
}

void WorldPipeline::notify_lod(const std::vector<LodKey>& published) {
  if (published.empty()) return;
  subscribers_.notify_lod(LodPublication{published, lod_->route(published)});
}

void WorldPipeline::lod_stats(PipelineStats& s) const {  // any thread
  s.lod_mesh_count = lod_->meshes().size();
  s.lod_mesh_bytes = lod_->memory_bytes();
  for (int level = 0; level < config_.lod.levels && level < LodStage::kCountedLevels; ++level) {
    s.lod_meshed.push_back(lod_->meshed(level));
    s.lod_remeshed.push_back(lod_->remeshed(level));
    s.lod_published.push_back(lod_->published(level));
  }
}

void WorldPipeline::lod_edited(const EditBatch& b, Clock::time_point now) {
  for (size_t t = 0; t < b.tasks.size(); ++t) {
    const auto* task = std::get_if<EditTask>(&b.tasks[t]);
    if (task && b.results[t].accepted) lod_->edited(world::touched_box(task->edit), now);
  }
}

}  // namespace vox::pipeline
