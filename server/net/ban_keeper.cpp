#include "server/net/ban_keeper.hpp"

#include <spdlog/spdlog.h>

#include <ctime>

#include "server/net/address_key.hpp"
#include "server/world/thread_name.hpp"

namespace vox::net {

BanKeeper::BanKeeper(std::unique_ptr<store::BanStore> store, std::chrono::milliseconds reload_every)
    : store_(std::move(store)), reload_every_(reload_every) {
  if (store_) read_store(false);
}

BanKeeper::~BanKeeper() { stop(); }

int64_t BanKeeper::now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void BanKeeper::start(OnNewBans on_new) {
  std::lock_guard lock(mutex_);
  if (started_ || stopping_) return;
  started_ = true;
  on_new_ = std::move(on_new);
  thread_ = std::thread([this] { run(); });
}

void BanKeeper::stop() {
  std::deque<Job> left;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    left.swap(jobs_);
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (Job& job : left)
    job.done({Outcome::Status::kStopped, "the server is shutting down", job.ban});
}

std::optional<store::Ban> BanKeeper::match(const std::string& player_id,
                                           const std::string& address) const {
  std::lock_guard lock(mutex_);
  return book_.match(player_id, address, now_ms());
}

BanBook::Page BanKeeper::page(const std::string& cursor, size_t max) const {
  std::lock_guard lock(mutex_);
  return book_.page(cursor, max, now_ms());
}

size_t BanKeeper::size() const {
  std::lock_guard lock(mutex_);
  return book_.size();
}

void BanKeeper::put(Ban b, Done done) { submit({true, std::move(b), std::move(done)}); }

void BanKeeper::remove(Ban::Kind kind, std::string target, Done done) {
  Ban key;
  key.kind = kind;
  key.target = std::move(target);
  submit({false, std::move(key), std::move(done)});
}

void BanKeeper::reload() {
  {
    std::lock_guard lock(mutex_);
    reload_now_ = true;
  }
  wake_.notify_all();
}

void BanKeeper::submit(Job job) {
  Outcome refused;
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || !started_) {
      refused = {Outcome::Status::kStopped, "the server is shutting down", job.ban};
    } else if (jobs_.size() >= kMaxQueued) {
      refused = {Outcome::Status::kBusy,
                 "over " + std::to_string(kMaxQueued) + " ban commands waiting; retry", job.ban};
    } else {
      jobs_.push_back(std::move(job));
      wake_.notify_all();
      return;
    }
  }
  job.done(refused);
}

void BanKeeper::run() {
  name_this_thread("vox-bans");
  auto next_reload = std::chrono::steady_clock::now() + reload_every_;
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait_until(lock, next_reload, [&] {
      return stopping_ || reload_now_ || !jobs_.empty() ||
             (store_ && std::chrono::steady_clock::now() >= next_reload);
    });
    if (stopping_) return;
    if (!jobs_.empty()) {
      Job job = std::move(jobs_.front());
      jobs_.pop_front();
      lock.unlock();
      apply(job);
      lock.lock();
      continue;
    }
    const bool asked = reload_now_;
    reload_now_ = false;
    lock.unlock();
    if (store_) {
      read_store(asked);
    } else {
      std::lock_guard book_lock(mutex_);
      book_.drop_ended(now_ms());
    }
    next_reload = std::chrono::steady_clock::now() + reload_every_;
    lock.lock();
  }
}

void BanKeeper::apply(Job& job) {
  Outcome out{Outcome::Status::kOk, "", job.ban};
  if (job.put) {
    {
      std::lock_guard lock(mutex_);
      if (!book_.contains(job.ban.kind, job.ban.target) && book_.size() >= store::kMaxBans)
        out = {Outcome::Status::kTooMany,
               "the world has " + std::to_string(store::kMaxBans) + " bans, the most it may have",
               job.ban};
    }
    if (out.status == Outcome::Status::kOk) {
      try {
        if (store_) store_->put(job.ban);
        std::lock_guard lock(mutex_);
        book_.put(job.ban);
      } catch (const store::StoreError& e) {
        out = {Outcome::Status::kUnavailable, e.what(), job.ban};
      }
    }
  } else {
    try {
      // The row goes whatever it held; the answer is OK only for a ban that was in force.
      if (store_) store_->remove(job.ban.kind, job.ban.target);
      std::optional<Ban> removed;
      {
        std::lock_guard lock(mutex_);
        removed = book_.remove(job.ban.kind, job.ban.target);
      }
      if (removed) out.ban = *removed;
      if (!removed || removed->expired(now_ms()))
        out = {Outcome::Status::kNotFound,
               std::string("no ban of that ") + store::to_string(job.ban.kind), job.ban};
    } catch (const store::StoreError& e) {
      out = {Outcome::Status::kUnavailable, e.what(), job.ban};
    }
  }
  job.done(out);
}

void BanKeeper::read_store(bool asked) {
  store::BanStore::Read read;
  try {
    read = store_->read(now_ms());
  } catch (const store::StoreError& e) {
    if (!started_) throw;  // the first read: voxeld does not start without its bans
    spdlog::warn("bans: could not read them again (the ones in force stay): {}", e.what());
    return;
  }
  // An address as admission counts it, whatever form the row has it in.
  for (Ban& b : read.bans) {
    if (b.kind != Ban::Kind::kAddress) continue;
    std::optional<std::string> key = address_key_of(b.target);
    if (!key) ++read.skipped, b.target.clear();
    if (key) b.target = std::move(*key);
  }
  std::erase_if(read.bans, [](const Ban& b) { return b.target.empty(); });
  if (read.skipped)
    spdlog::warn("bans: {} rows of {} are not valid bans and are ignored", read.skipped,
                 store_->name());
  if (read.over)
    spdlog::warn("bans: {} bans of {} are over the {} a world may have and are ignored", read.over,
                 store_->name(), store::kMaxBans);
  std::vector<Ban> added;
  size_t now_in_force = 0;
  {
    std::lock_guard lock(mutex_);
    added = book_.replace(std::move(read.bans), now_ms());
    now_in_force = book_.size();
  }
  if (asked || (!added.empty() && started_))
    spdlog::info("bans: {} in force ({} new) from {}", now_in_force, added.size(), store_->name());
  if (!added.empty() && on_new_) on_new_(added);
}

std::string describe_ban(const store::Ban& b) {
  std::string s = "banned";
  if (b.until_ms != 0) {
    const std::time_t t = static_cast<std::time_t>(b.until_ms / 1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char when[40];
    std::strftime(when, sizeof when, " until %Y-%m-%d %H:%M:%S UTC", &tm);
    s += when;
  }
  if (!b.reason.empty()) {
    s += ": ";
    s += b.reason;
  }
  return s;
}

}  // namespace vox::net
