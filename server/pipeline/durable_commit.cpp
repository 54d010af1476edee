#include "server/pipeline/durable_commit.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <unordered_set>

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

template <typename Future>
bool landed(const Future& f) {  // no append, or its outcome is in
  return !f.valid() || f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
}

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

DurableCommit::DurableCommit(store::WorldStore& store, std::chrono::milliseconds retry,
                             std::function<void()> landed, Hooks hooks)
    : retry_(retry),
      hooks_(std::move(hooks)),
      appender_(std::make_unique<StoreAppender>(store, std::move(landed))) {}

DurableCommit::~DurableCommit() = default;

void DurableCommit::start(EditBatch& b, std::optional<store::RegionWrite> regions) {
  const int64_t unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch())
                              .count();
  std::vector<store::LoggedEdit> log;
  log.reserve(b.accepted.size());
  // Sequence numbers are never reused, even after a failed append (its outcome may be in
  // doubt): the log may have gaps, never two edits with one number.
  for (size_t i = 0; i <= b.accepted.size(); ++i) {
    if (b.record && b.record->before == i) {  // a rollback, in its place among the edits
      store::LoggedEdit& r = log.emplace_back();
      r.seq = next_seq_++, r.unix_ms = unix_ms, r.author = b.record->by;
      r.undoes = b.record->undoes;
    }
    if (i == b.accepted.size()) break;
    const EditTask& t = *b.accepted[i];
    log.push_back({next_seq_++, unix_ms, t.author, t.edit, b.keep[i], t.edit_id, t.part});
  }
  if (!log.empty()) b.seqs = {log.front().seq, log.back().seq};  // else {0, 0}: regions only
  b.appended_at = Clock::now();
  // Appends that failed since the last that worked may have landed all the same: their
  // edits were undone here, so they go from the log with this append.
  std::vector<store::WorldStore::SeqRange> forget;
  if (doubtful_) forget.push_back(*doubtful_);
  std::shared_future<AppendOutcome> before;  // the newest append in flight
  for (auto it = pending_.rbegin(); it != pending_.rend() && !before.valid(); ++it)
    before = it->outcome;
  b.outcome =
      appender_->append(std::move(log), std::move(forget), std::move(before), std::move(regions));
}

uint64_t DurableCommit::edits_in_flight() const {
  uint64_t edits = 0;
  for (const EditBatch& b : pending_) edits += b.accepted.size();
  return edits;
}

bool DurableCommit::oldest_landed() const {
  return pending_.empty() || landed(pending_.front().outcome);
}

void DurableCommit::finish(size_t keep) {
  while (!pending_.empty()) {
    EditBatch& b = pending_.front();
    const Clock::time_point start = Clock::now();
    const bool ready = landed(b.outcome);
    if (!ready && pending_.size() <= keep) return;
    if (b.outcome.valid()) {
      const AppendOutcome& out = b.outcome.get();
      b.waited += ready ? 0 : seconds_since(start);
      if (hooks_.committed) hooks_.committed(out, b.waited);
      if (!out.error.empty()) return fail(out.error, out.fenced);
      doubtful_.reset();
      if (failing_) {
        failing_ = false;
        spdlog::info("world store: writing again; edits are accepted");
      }
    }
    hooks_.answer(b, true);
    pending_.pop_front();
  }
}

// The oldest pending append failed: every pending batch is undone (newest first) and its
// accepted edits refused; nothing of them was published.
void DurableCommit::fail(const std::string& error, bool fenced) {
  for (EditBatch& b : pending_) {
    if (b.outcome.valid()) b.outcome.wait();  // the later ones return without trying
  }
  for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) hooks_.undo(*it);
  // No append works in between, so one range covers every doubtful one (the later
  // batches' were not tried; forgetting them too is harmless).
  for (const EditBatch& b : pending_) {
    if (!b.outcome.valid() || b.seqs.first == 0) continue;  // not tried, or regions only
    if (!doubtful_) doubtful_ = b.seqs;
    doubtful_->last = b.seqs.last;
  }
  if (fenced) {  // a cluster zone moved: its holder now takes them (gateways ask it again)
    spdlog::info("world store: {}; the edits in flight were refused", error);
  } else {
    retry_at_ = Clock::now() + retry_;
    if (!failing_) spdlog::error("world store: {}; edits are refused until it works", error);
    failing_ = true;
  }
  for (EditBatch& b : pending_) {
    b.zone_moved = fenced;
    hooks_.answer(b, false);
  }
  pending_.clear();
}

MeshVersionPtr DurableCommit::newest_mesh(ChunkCoord c) const {
  for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) {
    const auto& dirty = it->dirty;
    const auto at = std::lower_bound(dirty.begin(), dirty.end(), c);
    if (at != dirty.end() && *at == c && it->fresh[at - dirty.begin()])
      return it->fresh[at - dirty.begin()];
  }
  return nullptr;
}

std::vector<ChunkCoord> DurableCommit::pending_chunks() const {
  std::vector<ChunkCoord> out;
  for (const EditBatch& b : pending_)
    for (const Undo::Patch& p : b.undo.patches) out.push_back(p.coord);
  return out;
}

bool DurableCommit::near_pending_edits(const std::vector<ChunkCoord>& chunks) const {
  if (pending_.empty() || chunks.empty()) return false;
  std::unordered_set<ChunkCoord, world::ChunkCoordHash> touched;
  for (const EditBatch& b : pending_)
    for (const Undo::Patch& p : b.undo.patches) touched.insert(p.coord);
  for (const ChunkCoord& c : chunks)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (touched.count(c.offset(dx, dy, dz))) return true;
  return false;
}

void DurableCommit::wait_for_appends() const {
  for (const EditBatch& b : pending_) {
    if (b.outcome.valid()) b.outcome.wait();
  }
}

}  // namespace vox::pipeline
