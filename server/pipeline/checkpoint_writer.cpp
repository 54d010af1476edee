#include "server/pipeline/checkpoint_writer.hpp"

#include <spdlog/spdlog.h>

#include <chrono>

#include "server/store/world_history.hpp"
#include "server/world/thread_name.hpp"

namespace vox::pipeline {

CheckpointWriter::CheckpointWriter(store::WorldStore& store, bool background,
                                   std::function<void()> on_done,
                                   const world::TerrainGenerator* history, std::mutex* history_lock)
    : store_(store), on_done_(std::move(on_done)), history_(history), history_lock_(history_lock) {
  if (background) thread_ = named_thread("vox-checkpoint", [this] { work(); });
}

CheckpointWriter::~CheckpointWriter() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

CheckpointResult CheckpointWriter::run(const CheckpointJob& job) {
  const auto start = std::chrono::steady_clock::now();
  CheckpointResult result{.seq = job.seq};
  std::vector<store::ChunkRecord> records;
  records.reserve(job.chunks.size());
  try {
    for (const auto& [c, live] : job.chunks) {
      std::optional<world::Chunk> copy;
      {
        std::lock_guard lock(mutex_);
        if (auto it = preserved_.find(c); it != preserved_.end()) {
          copy = std::move(it->second);
          preserved_.erase(it);
        } else {
          reading_ = c;
        }
      }
      std::vector<uint8_t> bytes = encoder_.encode(copy ? *copy : *live);
      {
        std::lock_guard lock(mutex_);
        reading_.reset();
        pending_.erase(c);
        bytes_ += bytes.size();
        if (copy) bytes_ -= copy->memory_bytes();
      }
      cv_.notify_all();  // preserve() may wait for this chunk
      result.bytes += bytes.size();
      result.coords.push_back(c);
      records.push_back({c, job.seq, std::move(bytes)});
    }
    // A window is kept by moving the history's base (keep_history), never by a trim that
    // would drop it; a trim of everything (--history-days 0) drops it.
    const bool whole = job.trim.through > 0 && !job.trim.windowed();
    store_.write_checkpoint(records, job.seq, whole || !history_ ? job.trim : store::LogTrim{0});
    result.ok = true;
    if (!whole && history_) keep_history(job);
  } catch (const std::exception& e) {  // the store's error, or no memory to encode
    {
      std::lock_guard lock(mutex_);
      reading_.reset();
    }
    cv_.notify_all();
    result.error = e.what();
    result.coords.clear();
    for (const auto& [c, live] : job.chunks) result.coords.push_back(c);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

void CheckpointWriter::keep_history(const CheckpointJob& job) {
  // Steps of a bounded size (store::advance_history), for at most this long per checkpoint:
  // a week-old backlog (a window shortened) goes over several.
  constexpr auto kBudget = std::chrono::seconds(2);
  const auto until = std::chrono::steady_clock::now() + kBudget;
  std::unique_lock<std::mutex> lock;
  if (history_lock_) {
    lock = std::unique_lock(*history_lock_, std::try_to_lock);
    if (!lock) return;  // a rollback reads the history: the next checkpoint moves it
  }
  try {
    for (;;) {
      const store::HistoryStep step =
          store::advance_history(store_, *history_, job.trim, job.seq, encoder_);
      if (step.reset)
        spdlog::info("world store: the history for rollbacks starts at edit {} (the checkpoint)",
                     step.through);
      if (step.reset || step.through == 0) return;
      const auto now = std::chrono::steady_clock::now();
      if (now >= until) {
        if (now - last_history_warning_ >= std::chrono::minutes(1)) {
          last_history_warning_ = now;
          spdlog::warn(
              "world store: the history's base lags the window (at edit {}); the log is longer "
              "than --history-days until it catches up",
              step.through);
        }
        return;
      }
    }
  } catch (const std::exception& e) {  // nothing is lost: the log keeps the edits meanwhile
    const auto now = std::chrono::steady_clock::now();
    if (now - last_history_warning_ >= std::chrono::minutes(1)) {
      last_history_warning_ = now;
      spdlog::warn("world store: the history's base did not move (the log keeps growing): {}",
                   e.what());
    }
  }
}

void CheckpointWriter::submit(CheckpointJob job) {
  {
    std::lock_guard lock(mutex_);
    pending_.clear();
    for (const auto& [c, live] : job.chunks) pending_.insert(c);
    busy_ = true;
    if (thread_.joinable()) {
      job_ = std::move(job);
    }
  }
  if (thread_.joinable()) {
    cv_.notify_all();
    return;
  }
  done(run(job));  // on this thread: nothing changes the chunks meanwhile
}

void CheckpointWriter::done(CheckpointResult r) {
  {
    std::lock_guard lock(mutex_);
    result_ = std::move(r);
    pending_.clear();
    preserved_.clear();
    bytes_ = 0;
    busy_ = false;
  }
  cv_.notify_all();
}

void CheckpointWriter::preserve(world::ChunkCoord c, const world::Chunk& live) {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return reading_ != c; });
  if (!pending_.count(c) || preserved_.count(c)) return;  // encoded already, or kept
  preserved_.emplace(c, live);
  bytes_ += live.memory_bytes();
}

std::optional<CheckpointResult> CheckpointWriter::take_result() {
  std::lock_guard lock(mutex_);
  return std::exchange(result_, std::nullopt);
}

void CheckpointWriter::wait() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [this] { return !busy_; });
}

size_t CheckpointWriter::memory_bytes() const {
  std::lock_guard lock(mutex_);
  return bytes_;
}

void CheckpointWriter::work() {
  for (;;) {
    CheckpointJob job;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return stopping_ || job_.has_value(); });
      if (!job_) return;  // stopping with nothing to write
      job = std::move(*job_);
      job_.reset();
    }
    done(run(job));
    if (on_done_) on_done_();
  }
}

}  // namespace vox::pipeline
