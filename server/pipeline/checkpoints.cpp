#include "server/pipeline/checkpoints.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

Checkpoints::Checkpoints(store::WorldStore& store, bool own_connection, CheckpointLimits limits,
                         LogRetention history, std::function<void()> wake, Clock::time_point now,
                         const world::TerrainGenerator* generator, std::mutex* history_lock)
    : limits_(limits),
      own_connection_(own_connection),
      history_(history),
      policy_(limits, now),
      writer_(std::make_unique<CheckpointWriter>(store, own_connection, std::move(wake), generator,
                                                 history_lock)) {}

bool Checkpoints::log_full(uint64_t log_tail) {
  const bool full = policy_.log_full(log_tail);
  if (full && !log_full_) {
    spdlog::warn(
        "world store: {} edits in the log await a checkpoint; edits are refused "
        "(SERVER_BUSY) until it is written",
        log_tail);
  } else if (!full && log_full_) {
    spdlog::info("world store: a checkpoint trimmed the log; edits are taken again");
  }
  log_full_ = full;
  return full;
}

std::optional<CheckpointResult> Checkpoints::start(WorldState& st, uint64_t seq,
                                                   Clock::time_point now) {
  CheckpointJob job{.seq = seq, .trim = history_.trim(seq, std::chrono::system_clock::now())};
  const std::vector<ChunkCoord> coords = take_unsaved(st, seq);
  for (const ChunkCoord& c : coords) {
    WorldState::ChunkInfo& info = st.info.at(c);  // unsaved chunks are never evicted
    info.unsaved = false;
    info.checkpointing = true;
  }
  // The writer reads the chunks themselves; a batch that changes one first preserves it,
  // so the checkpoint has every chunk as of `seq`.
  job.chunks.reserve(coords.size());
  for (const ChunkCoord& c : coords) job.chunks.emplace_back(c, st.chunks.find(c));
  checkpoint_edits_ = std::exchange(unsaved_edits_, 0);
  policy_.started(now);
  writer_->submit(std::move(job));
  if (own_connection_) return std::nullopt;
  return writer_->take_result();  // written on this thread: ready now
}

std::vector<ChunkCoord> Checkpoints::take_unsaved(WorldState& st, uint64_t seq) {
  if (!scope_) {
    std::vector<ChunkCoord> all(unsaved_.begin(), unsaved_.end());
    unsaved_.clear();
    return all;
  }
  CheckpointScope scope = scope_(seq);
  std::sort(scope.zones.begin(), scope.zones.end());
  std::sort(scope.whole.begin(), scope.whole.end());
  const auto in = [&](const std::vector<world::ZoneId>& zones, ChunkCoord c) {
    return std::binary_search(zones.begin(), zones.end(), world::zone_of(c, scope.zone_chunks));
  };
  if (!scope.whole.empty()) {
    for (auto& [c, info] : st.info) {
      if (!info.modified || !in(scope.whole, c)) continue;
      info.unsaved = true;
      unsaved_.insert(c);
    }
  }
  std::vector<ChunkCoord> out;
  for (const ChunkCoord& c : unsaved_) {
    if (in(scope.zones, c)) out.push_back(c);
  }
  unsaved_.clear();  // the rest: chunks of zones followed, or not writable now
  return out;
}

void Checkpoints::finish(WorldState& st, const CheckpointResult& r, Clock::time_point now) {
  policy_.finished(now, r.ok);
  for (const ChunkCoord& c : r.coords) {
    auto it = st.info.find(c);
    if (it == st.info.end()) continue;  // cannot happen: not evictable while written
    it->second.checkpointing = false;
    if (forgotten_.count(c)) continue;  // generated terrain now, saved
    if (r.ok) {
      st.stored.insert(c);
    } else if (!it->second.unsaved) {
      it->second.unsaved = true;
      unsaved_.insert(c);
    }
  }
  forgotten_.clear();
  if (!r.ok) unsaved_edits_ += checkpoint_edits_;
  checkpoint_edits_ = 0;
  if (r.ok) {
    spdlog::debug("checkpoint: {} chunks through edit {} ({} KiB) in {:.0f} ms", r.coords.size(),
                  r.seq, r.bytes >> 10, r.seconds * 1000);
    if (failing_) spdlog::info("checkpoint: writing again (through edit {})", r.seq);
  } else if (!failing_) {
    spdlog::error("checkpoint: {}; its chunks stay in memory, the log keeps their edits", r.error);
  }
  failing_ = !r.ok;
}

void Checkpoints::turn(WorldState& st, Clock::time_point now,
                       const std::function<uint64_t()>& drain, const Finished& finished,
                       bool may_start) {
  if (auto r = take_result()) {
    drain();
    finish(st, *r, now);
    finished(*r);
  }
  if (!may_start || !due(now)) return;
  const uint64_t seq = drain();
  // Every applied edit, and no other; written on this thread without a second connection.
  if (auto r = start(st, seq, now)) {
    finish(st, *r, Clock::now());
    finished(*r);
  }
}

void Checkpoints::last(WorldState& st, uint64_t seq, const Finished& finished) {
  const auto take_in = [&] {
    if (auto r = take_result()) {
      finish(st, *r, Clock::now());
      finished(*r);
    }
  };
  wait();
  take_in();
  if (!has_unsaved()) return;
  const size_t chunks = unsaved_chunks();
  if (auto r = start(st, seq, Clock::now())) {
    finish(st, *r, Clock::now());
    finished(*r);
  }
  wait();
  take_in();
  if (!has_unsaved())
    spdlog::info("checkpoint at shutdown: {} chunks through edit {}", chunks, seq);
}

}  // namespace vox::pipeline
