#include "server/pipeline/checkpoint_writer.hpp"

#include <chrono>

namespace vox::pipeline {

namespace {

size_t job_memory(const CheckpointJob& job) {
  size_t bytes = 0;
  for (const store::ChunkRecord& r : job.records) bytes += r.samples.capacity() + sizeof(r);
  return bytes;
}

}  // namespace

CheckpointWriter::CheckpointWriter(store::WorldStore& store, bool background,
                                   std::function<void()> on_done)
    : store_(store), on_done_(std::move(on_done)) {
  if (background) thread_ = std::thread([this] { work(); });
}

CheckpointWriter::~CheckpointWriter() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

CheckpointResult CheckpointWriter::write(store::WorldStore& store, const CheckpointJob& job) {
  const auto start = std::chrono::steady_clock::now();
  CheckpointResult result{.seq = job.seq};
  for (const store::ChunkRecord& r : job.records) {
    result.bytes += r.samples.size();
    result.coords.push_back(r.coord);
  }
  try {
    store.write_checkpoint(job.records, job.seq, job.trim_through);
    result.ok = true;
  } catch (const std::exception& e) {
    result.error = e.what();
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

void CheckpointWriter::submit(CheckpointJob job) {
  if (!thread_.joinable()) {
    CheckpointResult r = write(store_, job);
    std::lock_guard lock(mutex_);
    result_ = std::move(r);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    job_bytes_ = job_memory(job);
    job_ = std::move(job);
    busy_ = true;
  }
  cv_.notify_all();
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
  return job_bytes_;
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
    CheckpointResult r = write(store_, job);
    job = {};  // the records go before the memory they count is given back
    {
      std::lock_guard lock(mutex_);
      result_ = std::move(r);
      job_bytes_ = 0;
      busy_ = false;
    }
    cv_.notify_all();
    if (on_done_) on_done_();
  }
}

}  // namespace vox::pipeline
