#include "server/pipeline/store_appender.hpp"

#include <algorithm>
#include <span>

#include "server/store/zone_leases.hpp"
#include "server/world/thread_name.hpp"

namespace vox::pipeline {

StoreAppender::StoreAppender(store::WorldStore& store, std::function<void()> landed)
    : store_(store),
      landed_(std::move(landed)),
      thread_(named_thread("vox-appender", [this] { work(); })) {}

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
    std::vector<Job> group = take_group();
    lock.unlock();
    run(group);
    if (landed_) landed_();
    lock.lock();
  }
}

std::vector<StoreAppender::Job> StoreAppender::take_group() {
  std::vector<Job> group;
  group.push_back(std::move(jobs_.front()));
  jobs_.pop_front();
  while (!group.front().regions && !jobs_.empty() && !jobs_.front().regions &&
         group.size() < kMaxGroup) {
    group.push_back(std::move(jobs_.front()));
    jobs_.pop_front();
  }
  return group;
}

void StoreAppender::run(std::vector<Job>& group) {
  AppendOutcome out;
  // Each append is given after the one before it: only the first's `before` can have
  // landed already (the others' are in this group, not set yet).
  const Job& head = group.front();
  if (head.before.valid() && !head.before.get().error.empty()) {
    out.error = "not tried: an earlier append failed";
  } else {
    const auto start = std::chrono::steady_clock::now();
    try {
      std::vector<store::LoggedEdit> log = std::move(group.front().log);
      std::vector<store::WorldStore::SeqRange> forget = std::move(group.front().forget);
      for (Job& job : std::span(group).subspan(1)) {
        log.insert(log.end(), std::make_move_iterator(job.log.begin()),
                   std::make_move_iterator(job.log.end()));
        for (const auto& r : job.forget) {  // the appends of a group carry the same ranges
          const bool seen = std::any_of(forget.begin(), forget.end(), [&](const auto& f) {
            return f.first == r.first && f.last == r.last;
          });
          if (!seen) forget.push_back(r);
        }
      }
      out.edits = log.size();
      store_.append_edits(log, forget, head.regions ? &*head.regions : nullptr);
    } catch (const store::FencedError& e) {  // a cluster zone moved to another node
      out.error = e.what();
      out.fenced = true;
    } catch (const std::exception& e) {  // the store's, or no memory for the merged log
      out.error = e.what();
      if (out.error.empty()) out.error = "append failed";
    } catch (...) {
      out.error = "append failed";
    }
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  for (Job& job : group) {
    job.promise.set_value(out);
    out.first = false;
  }
}

}  // namespace vox::pipeline
