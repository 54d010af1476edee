#include "server/pipeline/stats_book.hpp"

#include <spdlog/spdlog.h>

#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

void StatsBook::residency(PipelineStats& s, const WorldState& st) {
  s.loaded_chunks = st.chunks.size();
  s.modified_chunks = st.modified_count;
  s.chunk_bytes = st.chunks.memory_bytes();
  s.stored_chunks = st.stored.size();
}

void StatsBook::count(const BatchCounts& delta, const WorldState& st, size_t unsaved_chunks) {
  batch_.edits_applied += delta.edits_applied;
  batch_.edits_refused += delta.edits_refused;
  batch_.meshes_published += delta.meshes_published;
  batch_.chunks_generated += delta.chunks_generated;
  std::lock_guard lock(mutex_);
  stats_.edits_applied += delta.edits_applied;
  stats_.edits_refused += delta.edits_refused;
  stats_.edits_refused_busy += delta.edits_refused_busy;
  stats_.meshes_published += delta.meshes_published;
  stats_.chunks_generated += delta.chunks_generated;
  residency(stats_, st);
  stats_.unsaved_chunks = unsaved_chunks;
}

void StatsBook::log_slow(double took, size_t loaded) const {
  spdlog::warn(
      "pipeline: a batch took {:.0f} ms ({} edits, {} chunks loaded, {} generated, {} meshes "
      "published)",
      took * 1000, batch_.edits_applied + batch_.edits_refused, loaded, batch_.chunks_generated,
      batch_.meshes_published);
}

}  // namespace vox::pipeline
