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
                     const world::TerrainGenerator& generator, size_t max_chunks)
    : pipeline_(pipeline), store_(store), generator_(generator), max_chunks_(max_chunks) {
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

RollbackReport Rollbacks::run(const Job& job) {
  // 1. The plan, as of the edits logged so far.
  uint64_t through = freeze({});
  if (!wait_durable(through))
    return failed(Status::kUnavailable, "the world store is not keeping up; nothing changed");
  store::RollbackOutcome o =
      store::prepare_rollback(store_, generator_, job.query, through, true, max_chunks_);
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
  // 2., 3. Freeze, recompute; again while the set grew.
  std::set<ChunkCoord> frozen;
  std::vector<ChunkCoord> more = o.chunks;
  const auto thaw_all = [&] { thaw({frozen.begin(), frozen.end()}); };
  for (int round = 0;; ++round) {
    if (round == kMaxFreezes) {
      thaw_all();
      return failed(Status::kBusy, "the area kept changing while it was recomputed; retry");
    }
    frozen.insert(more.begin(), more.end());
    through = freeze(std::move(more));
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return thaw_all(), failed(Status::kStopped, "the server is stopping");
    }
    if (!wait_durable(through)) {
      thaw_all();
      return failed(Status::kUnavailable, "the world store is not keeping up; nothing changed");
    }
    o = store::prepare_rollback(store_, generator_, job.query, through, false, max_chunks_);
    if (!o.refusal.empty() || o.too_many || o.undoes.empty()) return thaw_all(), report(o);
    more.clear();
    for (const ChunkCoord& c : o.chunks)
      if (!frozen.count(c)) more.push_back(c);
    if (more.empty()) break;
  }
  // 4. In place, in slices; the first logs the record.
  RollbackReport r = report(o);
  std::vector<std::pair<ChunkCoord, world::Chunk>>& chunks = o.recomputed;
  for (size_t from = 0; from < chunks.size(); from += kSlice) {
    const size_t n = std::min(kSlice, chunks.size() - from);
    std::vector<std::pair<ChunkCoord, world::Chunk>> slice;
    for (size_t i = 0; i < n; ++i) slice.push_back(chunks[from + i]);  // kept to try again
    const bool first = from == 0;
    std::optional<uint64_t> seq;
    for (int attempt = 0; !seq; ++attempt) {
      seq = install(slice, first ? &o.undoes : nullptr, job.by);
      if (seq) break;
      if (first) {  // nothing of it is in the world or the log
        thaw_all();
        return failed(Status::kUnavailable,
                      "the world store could not log the rollback; nothing changed");
      }
      // The record is durable: its chunks must go in (a later failure undid the slice).
      std::this_thread::sleep_for(std::chrono::milliseconds(std::min(1000, 50 << attempt)));
    }
    if (first) r.record = *seq;
    for (auto& [c, chunk] : slice) frozen.erase(c);
  }
  thaw_all();  // frozen by an earlier round, not recomputed in the end
  return r;
}

uint64_t Rollbacks::freeze(std::vector<ChunkCoord> coords) {
  std::promise<uint64_t> through;
  RollbackTask t;
  t.kind = RollbackTask::Kind::kFreeze;
  t.coords = std::move(coords);
  t.done = [&through](bool, uint64_t seq) { through.set_value(seq); };
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
                                           const std::string& by) {
  std::promise<std::optional<uint64_t>> landed;
  RollbackTask t;
  t.kind = RollbackTask::Kind::kInstall;
  t.chunks = std::move(chunks);
  if (undoes) t.undoes = *undoes;
  t.by = by;
  t.done = [&landed](bool ok, uint64_t seq) {
    landed.set_value(ok ? std::optional<uint64_t>(seq) : std::nullopt);
  };
  pipeline_.submit_rollback(std::move(t));
  return landed.get_future().get();
}

bool Rollbacks::wait_durable(uint64_t through) {
  const auto give_up = std::chrono::steady_clock::now() + kDurableWait;
  while (store_.info().last_seq < through) {
    if (std::chrono::steady_clock::now() >= give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace vox::pipeline
