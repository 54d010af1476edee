#include "server/cluster/edit_forwarder.hpp"

#include <spdlog/spdlog.h>

#include <random>
#include <tuple>
#include <vector>

#include "server/cluster/zone_wire.hpp"
#include "server/world/thread_name.hpp"

namespace vox::cluster {

namespace {

std::string random_inbox() {
  std::random_device rd;
  const uint64_t v = (uint64_t{rd()} << 32) ^ rd();
  char buf[40];
  std::snprintf(buf, sizeof buf, "_INBOX.vox%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace

EditForwarder::EditForwarder(NatsLink& nats, Config config,
                             std::function<void(world::ZoneId)> nobody_holds)
    : nats_(nats),
      config_(std::move(config)),
      nobody_holds_(std::move(nobody_holds)),
      inbox_(random_inbox()) {
  subscription_ = nats_.subscribe(inbox_ + ".*", [this](const NatsMessage& m) { on_reply(m); });
  thread_ = named_thread("vox-forward", [this] { run(); });
}

EditForwarder::~EditForwarder() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  nats_.unsubscribe(subscription_);
  std::map<uint64_t, Pending> left;
  {
    std::lock_guard lock(mutex_);
    left.swap(pending_);
  }
  for (auto& [id, p] : left)
    p.done(refusal(id, world::RefusalReason::kShuttingDown, "the server is shutting down"));
}

EditReply EditForwarder::refusal(uint64_t id, world::RefusalReason reason, std::string message) {
  EditReply r;
  r.id = id;
  r.reason = reason;
  r.message = std::move(message);
  return r;
}

void EditForwarder::forward(world::ZoneId zone, EditRequest request, Done done) {
  std::unique_lock lock(mutex_);
  if (pending_.size() >= config_.max_pending) {
    lock.unlock();
    return done(refusal(0, world::RefusalReason::kServerBusy,
                        "too many edits wait for other nodes; retry shortly"));
  }
  request.id = next_id_++;
  forwarded_.fetch_add(1, std::memory_order_relaxed);
  std::vector<uint8_t> bytes = encode_edit_request(request);
  pending_[request.id] = Pending{std::move(done), zone, Clock::now() + config_.timeout, bytes};
  lock.unlock();
  send(zone, request.id, bytes);
}

void EditForwarder::send(world::ZoneId zone, uint64_t id, const std::vector<uint8_t>& request) {
  try {
    nats_.publish(zone_subject(config_.world, zone, "edit"), request,
                  inbox_ + "." + std::to_string(id));
  } catch (const ClusterError& e) {
    std::unique_lock again(mutex_);
    const auto it = pending_.find(id);
    if (it == pending_.end()) return;  // answered meanwhile
    Done d = std::move(it->second.done);
    pending_.erase(it);
    again.unlock();
    d(refusal(id, world::RefusalReason::kStorageUnavailable,
              std::string("the cluster's messaging is down (") + e.what() + "); retry"));
  }
}

void EditForwarder::on_reply(const NatsMessage& m) {
  const size_t dot = m.subject.rfind('.');
  uint64_t id = 0;
  try {
    id = std::stoull(m.subject.substr(dot + 1));
  } catch (const std::exception&) {
    return;
  }
  std::string why;
  std::optional<EditReply> reply;
  if (!m.no_responders) reply = decode_edit_reply(m.data, &why);
  const Clock::time_point now = Clock::now();
  std::unique_lock lock(mutex_);
  const auto it = pending_.find(id);
  if (it == pending_.end()) return;  // timed out already
  Pending& waiting = it->second;
  // The zone is moving (nobody holds it yet, or its holder cannot write it now): asked
  // again shortly, while there is time.
  const bool moving = m.no_responders || (reply && reply->zone_moving);
  if (moving && now + config_.retry < waiting.deadline) {
    waiting.unheld = m.no_responders;
    if (reply) waiting.moving = std::move(reply);
    waiting.again_at = now + config_.retry;
    const world::ZoneId zone = waiting.zone;
    lock.unlock();
    if (m.no_responders) {
      unheld_.fetch_add(1, std::memory_order_relaxed);
      nobody_holds_(zone);
    }
    wake_.notify_one();
    return;
  }
  Pending p = std::move(waiting);
  pending_.erase(it);
  lock.unlock();
  if (m.no_responders) {
    unheld_.fetch_add(1, std::memory_order_relaxed);
    nobody_holds_(p.zone);
    return p.done(unheld_refusal(id, p.zone));
  }
  if (!reply) {
    const uint64_t damaged = ++damaged_;
    if (damaged % 1000 == 1)  // one line per thousand
      spdlog::warn("cluster: a damaged edit reply: {} [{} so far]", why, damaged);
    return p.done(refusal(id, world::RefusalReason::kStorageUnavailable,
                          "the zone's holder answered in a form this node cannot read"));
  }
  p.done(*reply);
}

EditReply EditForwarder::unheld_refusal(uint64_t id, world::ZoneId zone) {
  return refusal(id, world::RefusalReason::kStorageUnavailable,
                 "zone (" + std::to_string(zone.x) + ", " + std::to_string(zone.z) +
                     ") is held by no node right now: it is being taken; retry shortly");
}

void EditForwarder::run() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    // Retries are due within `retry`; timeouts are checked as often.
    wake_.wait_for(lock, pending_.empty() ? std::chrono::milliseconds(200) : config_.retry,
                   [this] { return stopping_; });
    if (stopping_) break;
    lock.unlock();
    sweep();
    lock.lock();
  }
}

void EditForwarder::sweep() {
  const Clock::time_point now = Clock::now();
  std::vector<std::pair<uint64_t, Pending>> late;
  std::vector<std::tuple<world::ZoneId, uint64_t, std::vector<uint8_t>>> again;
  {
    std::lock_guard lock(mutex_);
    for (auto it = pending_.begin(); it != pending_.end();) {
      Pending& p = it->second;
      if (p.deadline <= now) {
        late.emplace_back(it->first, std::move(p));
        it = pending_.erase(it);
        continue;
      }
      if (p.again_at && *p.again_at <= now) {
        p.again_at.reset();
        again.emplace_back(p.zone, it->first, p.request);
      }
      ++it;
    }
  }
  for (auto& [zone, id, request] : again) {
    retried_.fetch_add(1, std::memory_order_relaxed);
    send(zone, id, request);
  }
  for (auto& [id, p] : late) {
    if (p.again_at) {  // it was still moving: refused as its last answer said
      p.done(p.moving && !p.unheld ? *p.moving : unheld_refusal(id, p.zone));
      continue;
    }
    timed_out_.fetch_add(1, std::memory_order_relaxed);
    nobody_holds_(p.zone);  // its holder may have died or stalled: the next live one takes it
    EditReply unknown = refusal(id, world::RefusalReason::kStorageUnavailable,
                                "the zone's holder did not answer in time; the edit may have "
                                "been applied");
    unknown.maybe_applied = true;
    p.done(unknown);
  }
}

size_t EditForwarder::pending() const {
  std::lock_guard lock(mutex_);
  return pending_.size();
}

}  // namespace vox::cluster
