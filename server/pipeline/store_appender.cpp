#include "server/pipeline/store_appender.hpp"

namespace vox::pipeline {

StoreAppender::StoreAppender(store::WorldStore& store, std::function<void()> landed)
    : store_(store), landed_(std::move(landed)), thread_([this] { work(); }) {}

StoreAppender::~StoreAppender() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_one();
  thread_.join();
}

std::shared_future<AppendOutcome> StoreAppender::append(
    std::vector<store::LoggedEdit> log, std::vector<store::WorldStore::SeqRange> forget,
    std::shared_future<AppendOutcome> before, std::optional<store::RegionWrite> regions) {
  Job job{std::move(log), std::move(forget), std::move(regions), std::move(before), {}};
  std::shared_future<AppendOutcome> outcome = job.promise.get_future().share();
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  cv_.notify_one();
  return outcome;
}

void StoreAppender::work() {
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
    if (jobs_.empty()) return;  // stopping, and everything queued has run
    Job job = std::move(jobs_.front());
    jobs_.pop_front();
    lock.unlock();
    job.promise.set_value(run(job));
    if (landed_) landed_();
    lock.lock();
  }
}

AppendOutcome StoreAppender::run(Job& job) {
  AppendOutcome out;
  if (job.before.valid() && !job.before.get().error.empty()) {
    out.error = "not tried: an earlier append failed";
    return out;
  }
  const auto start = std::chrono::steady_clock::now();
  try {
    store_.append_edits(job.log, job.forget, job.regions ? &*job.regions : nullptr);
  } catch (const std::exception& e) {
    out.error = e.what();
    if (out.error.empty()) out.error = "append failed";
  } catch (...) {
    out.error = "append failed";
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace vox::pipeline
