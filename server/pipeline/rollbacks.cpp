#include "server/pipeline/rollbacks.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <set>

#include "server/pipeline/world_pipeline.hpp"
#include "server/world/thread_name.hpp"

namespace vox::pipeline {

using world::ChunkCoord;
using Status = RollbackReport::Status;

namespace {

// How often the recomputation may find that edits grew its set while it froze more.
constexpr int kMaxFreezes = 4;
// How often a slice after the record is tried (backing off to 0.8 s): about 10 s.
constexpr int kMaxSliceTries = 15;
// How long the store may take to hold the edits before a freeze.
constexpr auto kDurableWait = std::chrono::seconds(10);

RollbackReport failed(Status s, std::string message) {
  RollbackReport r;
  r.status = s;
  r.message = std::move(message);
  return r;
}

}  // namespace

Rollbacks::Rollbacks(WorldPipeline& pipeline, store::WorldStore& store,
                     const world::TerrainGenerator& generator, size_t max_chunks,
                     std::mutex& history_lock, bool keeps_history)
    : pipeline_(pipeline),
      store_(store),
      generator_(generator),
      max_chunks_(max_chunks),
      history_lock_(history_lock),
      keeps_history_(keeps_history) {
  thread_ = named_thread("vox-rollback", [this] { work(); });
}

Rollbacks::~Rollbacks() { stop(); }

void Rollbacks::submit(Job job) {
  {
    std::lock_guard lock(mutex_);
    if (!stopping_ && queue_.size() < kMaxQueued) {
      queue_.push_back(std::move(job));
      cv_.notify_one();
      return;
    }
  }
  const bool stopped = [&] {
    std::lock_guard lock(mutex_);
    return stopping_;
  }();
  if (job.done)
    job.done(stopped ? failed(Status::kStopped, "the server is stopping")
                     : failed(Status::kBusy, "rollbacks are queued already; retry later"));
}

void Rollbacks::stop() {
  std::deque<Job> dropped;
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && !thread_.joinable()) return;
    stopping_ = true;
    dropped.swap(queue_);
  }
  cv_.notify_all();
  for (Job& j : dropped)
    if (j.done) j.done(failed(Status::kStopped, "the server is stopping"));
  if (thread_.joinable()) thread_.join();
}

void Rollbacks::work() {
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    const auto start = std::chrono::steady_clock::now();
    RollbackReport r;
    try {
      r = run(job);
    } catch (const std::exception& e) {  // the store's error, or no memory
      r = failed(Status::kUnavailable, e.what());
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    spdlog::info("rollback by {}: {} ({} edits, {} chunks, record {}, {:.2f} s){}{}",
                 job.by.empty() ? "-" : job.by,
                 r.status == Status::kOk ? (job.dry_run ? "planned" : "done") : "not done", r.edits,
                 r.chunks, r.record, r.seconds, r.message.empty() ? "" : ": ", r.message);
    if (job.done) job.done(r);
  }
}

bool Rollbacks::stopping() {
  std::lock_guard lock(mutex_);
  return stopping_;
}

RollbackReport Rollbacks::run(const Job& job) {
  if (!keeps_history_)
    return failed(Status::kRefused,
                  "this server keeps no history (voxeld --history-days 0): nothing to roll back");
  // The history's base stays where it is until the record is logged (CheckpointWriter).
  std::unique_lock history(history_lock_);
  // 1. The plan, as of the edits logged so far.
  const auto unavailable = [] {
    return failed(Status::kUnavailable,
                  "the world store is failing or behind (an append in doubt is not read); "
                  "nothing changed; retry once it works");
  };
  std::optional<uint64_t> through = freeze({});
  if (!through || !wait_durable(*through)) return unavailable();
  store::RollbackOutcome o =
      store::prepare_rollback(store_, generator_, job.query, *through, true, max_chunks_);
  const auto report = [](const store::RollbackOutcome& x) {
    RollbackReport r;
    r.edits = x.edits, r.chunks = x.chunks.size();
    r.history_from = x.history_from, r.history_from_ms = x.history_from_ms;
    if (!x.refusal.empty()) r.status = Status::kRefused, r.message = x.refusal;
    if (x.too_many)
      r.status = Status::kTooMany,
      r.message = "it would recompute more chunks than a rollback may (narrow it: a box, a time)";
    return r;
  };
  if (job.dry_run || !o.refusal.empty() || o.too_many || o.undoes.empty()) return report(o);
  // 2., 3. Freeze, recompute; again while the set grew. Whatever happens, what is still
  // frozen thaws when this returns (or throws).
  std::set<ChunkCoord> frozen;
  struct Thaw {
    Rollbacks& self;
    std::set<ChunkCoord>& frozen;
    ~Thaw() {
      if (!frozen.empty()) self.thaw({frozen.begin(), frozen.end()});
    }
  } thaw_guard{*this, frozen};
  std::vector<ChunkCoord> more = o.chunks;
  for (int round = 0;; ++round) {
    if (round == kMaxFreezes)
      return failed(Status::kBusy, "the area kept changing while it was recomputed; retry");
    if (stopping()) return failed(Status::kStopped, "the server is stopping");
    frozen.insert(more.begin(), more.end());
    through = freeze(std::move(more));
    if (!through || !wait_durable(*through)) return unavailable();
    o = store::prepare_rollback(store_, generator_, job.query, *through, false, max_chunks_);
    if (!o.refusal.empty() || o.too_many || o.undoes.empty()) return report(o);
    more.clear();
    for (const ChunkCoord& c : o.chunks)
      if (!frozen.count(c)) more.push_back(c);
    if (more.empty()) break;
  }
  // 4. In place, in slices; the first logs the record. From then on the rollback is
  // finished even at stop (the pipeline writes no checkpoint past the record meanwhile).
  RollbackReport r = report(o);
  std::vector<std::pair<ChunkCoord, world::Chunk>>& chunks = o.recomputed;
  for (size_t from = 0; from < chunks.size(); from += kSlice) {
    const size_t n = std::min(kSlice, chunks.size() - from);
    std::vector<std::pair<ChunkCoord, world::Chunk>> slice;
    slice.reserve(n);
    for (size_t i = 0; i < n; ++i) slice.push_back(chunks[from + i]);  // kept to try again
    const bool first = from == 0, last = from + n == chunks.size();
    std::optional<uint64_t> seq;
    for (int attempt = 0; !seq; ++attempt) {
      seq = install(slice, first ? &o.undoes : nullptr, job.by, last);
      if (seq) break;
      if (first)  // not logged, unless its append is in doubt (then forgotten by the next)
        return failed(Status::kUnavailable,
                      "the world store failed while logging the rollback; nothing changed "
                      "(voxel-cli world log shows no record of it); retry once it works");
      if (attempt == kMaxSliceTries) {
        spdlog::error(
            "rollback {}: {} of its chunks could not be put in place (the store cannot read "
            "what they replace); no checkpoint is written until voxeld restarts and replays "
            "it",
            r.record, chunks.size() - from);
        r.status = Status::kUnavailable;
        r.message = "logged as rollback " + std::to_string(r.record) +
                    ", but not all its chunks are in place: restart voxeld to replay it";
        frozen.clear();  // stays frozen: no edit may land on what the replay recomputes
        return r;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50 << std::min(attempt, 4)));
    }
    if (first) {
      r.record = *seq;
      history.unlock();
    }
    for (auto& [c, chunk] : slice) frozen.erase(c);
  }
  return r;  // the guard thaws what an earlier round froze and the end did not recompute
}

std::optional<uint64_t> Rollbacks::freeze(std::vector<ChunkCoord> coords) {
  std::promise<std::optional<uint64_t>> through;
  RollbackTask t;
  t.kind = RollbackTask::Kind::kFreeze;
  t.coords = std::move(coords);
  t.done = [&through](bool ok, uint64_t seq) {
    through.set_value(ok ? std::optional<uint64_t>(seq) : std::nullopt);
  };
  pipeline_.submit_rollback(std::move(t));
  return through.get_future().get();
}

void Rollbacks::thaw(std::vector<ChunkCoord> coords) {
  if (coords.empty()) return;
  std::promise<void> done;
  RollbackTask t;
  t.kind = RollbackTask::Kind::kThaw;
  t.coords = std::move(coords);
  t.done = [&done](bool, uint64_t) { done.set_value(); };
  pipeline_.submit_rollback(std::move(t));
  done.get_future().get();
}

std::optional<uint64_t> Rollbacks::install(std::vector<std::pair<ChunkCoord, world::Chunk>> chunks,
                                           const std::vector<uint64_t>* undoes,
                                           const std::string& by, bool last) {
  std::promise<std::optional<uint64_t>> landed;
  RollbackTask t;
  t.kind = RollbackTask::Kind::kInstall;
  t.chunks = std::move(chunks);
  if (undoes) t.undoes = *undoes;
  t.by = by;
  t.last = last;
  t.done = [&landed](bool ok, uint64_t seq) {
    landed.set_value(ok ? std::optional<uint64_t>(seq) : std::nullopt);
  };
  pipeline_.submit_rollback(std::move(t));
  return landed.get_future().get();
}

bool Rollbacks::wait_durable(uint64_t through) {
  const auto give_up = std::chrono::steady_clock::now() + kDurableWait;
  while (store_.last_seq() < through) {
    if (std::chrono::steady_clock::now() >= give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace vox::pipeline
