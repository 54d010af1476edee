#include "server/cluster/nats_link.hpp"

#include <nats/nats.h>

#include <condition_variable>

namespace vox::cluster {
namespace {

// The URL without credentials a caller might have put in it, for messages.
std::string redact(const std::string& url) {
  const auto scheme = url.find("://");
  const auto at = url.find('@');
  if (scheme == std::string::npos || at == std::string::npos || at < scheme) return url;
  return url.substr(0, scheme + 3) + "***" + url.substr(at);
}

void check(natsStatus s, const std::string& what) {
  if (s != NATS_OK) throw ClusterError(what + ": " + natsStatus_GetText(s));
}

}  // namespace

struct NatsLink::Connection {
  natsConnection* nc = nullptr;
  ~Connection() {
    if (nc) natsConnection_Destroy(nc);  // closes; waits for handlers in progress
  }
};

struct NatsLink::Subscription {
  Handler handler;
  natsSubscription* sub = nullptr;
  std::mutex mutex;
  std::condition_variable done_cv;
  bool done = false;  // closed, and its handler will not run again
  ~Subscription() {
    if (sub) natsSubscription_Destroy(sub);
  }
  // Unsubscribes and waits until a handler in progress has returned: only then may the
  // handler's closure go.
  void close() {
    if (natsSubscription_Unsubscribe(sub) != NATS_OK) return;  // already closed with the link
    std::unique_lock lock(mutex);
    done_cv.wait_for(lock, std::chrono::seconds(10), [&] { return done; });
  }
  static void on_complete(void* closure) {
    auto* self = static_cast<Subscription*>(closure);
    std::lock_guard lock(self->mutex);
    self->done = true;
    self->done_cv.notify_all();
  }
  static void on_message(natsConnection*, natsSubscription*, natsMsg* msg, void* closure) {
    const auto* self = static_cast<const Subscription*>(closure);
    const char* reply = natsMsg_GetReply(msg);
    const NatsMessage m{natsMsg_GetSubject(msg),
                        reply ? reply : "",
                        {reinterpret_cast<const uint8_t*>(natsMsg_GetData(msg)),
                         static_cast<size_t>(natsMsg_GetDataLength(msg))},
                        natsMsg_IsNoResponders(msg)};
    try {
      self->handler(m);
    } catch (...) {  // a handler's failure stays with that message
    }
    natsMsg_Destroy(msg);
  }
};

NatsLink::NatsLink(const NatsConfig& config)
    : server_(redact(config.url)), conn_(std::make_unique<Connection>()) {
  natsOptions* opts = nullptr;
  check(natsOptions_Create(&opts), "NATS " + server_);
  const auto destroy_opts =
      std::unique_ptr<natsOptions, void (*)(natsOptions*)>(opts, natsOptions_Destroy);
  const std::string where = "NATS " + server_;
  check(natsOptions_SetURL(opts, config.url.c_str()), where);
  if (!config.user.empty())
    check(natsOptions_SetUserInfo(opts, config.user.c_str(), config.password.c_str()), where);
  if (!config.name.empty()) check(natsOptions_SetName(opts, config.name.c_str()), where);
  check(natsOptions_SetTimeout(opts, config.connect_timeout.count()), where);
  check(natsOptions_SetMaxReconnect(opts, -1), where);  // forever: the server comes back
  check(natsOptions_SetReconnectWait(opts, 250), where);
  check(natsOptions_SetFailRequestsOnDisconnect(opts, true), where);
  check(natsOptions_SetReconnectedCB(
            opts,
            [](natsConnection*, void* closure) {
              static_cast<std::atomic<uint64_t>*>(closure)->fetch_add(1);
            },
            &reconnects_),
        where);
  check(natsConnection_Connect(&conn_->nc, opts), "cannot connect to " + where);
}

NatsLink::~NatsLink() {
  std::map<uint64_t, std::unique_ptr<Subscription>> subs;
  {
    std::lock_guard lock(mutex_);
    subs.swap(subscriptions_);
  }
  for (auto& [id, s] : subs) s->close();
  subs.clear();
  conn_.reset();
}

void NatsLink::publish(const std::string& subject, std::span<const uint8_t> data,
                       const std::string& reply) {
  const natsStatus s =
      reply.empty() ? natsConnection_Publish(conn_->nc, subject.c_str(), data.data(),
                                             static_cast<int>(data.size()))
                    : natsConnection_PublishRequest(conn_->nc, subject.c_str(), reply.c_str(),
                                                    data.data(), static_cast<int>(data.size()));
  check(s, "NATS " + server_ + ": publish on " + subject);
}

std::optional<std::vector<uint8_t>> NatsLink::request(const std::string& subject,
                                                      std::span<const uint8_t> data,
                                                      std::chrono::milliseconds timeout) {
  natsMsg* reply = nullptr;
  const natsStatus s = natsConnection_Request(&reply, conn_->nc, subject.c_str(), data.data(),
                                              static_cast<int>(data.size()), timeout.count());
  if (s == NATS_TIMEOUT) return std::nullopt;
  if (s == NATS_NO_RESPONDERS)
    throw ClusterError("NATS " + server_ + ": nobody answers on " + subject);
  check(s, "NATS " + server_ + ": request on " + subject);
  const auto* bytes = reinterpret_cast<const uint8_t*>(natsMsg_GetData(reply));
  std::vector<uint8_t> out(bytes, bytes + natsMsg_GetDataLength(reply));
  natsMsg_Destroy(reply);
  return out;
}

uint64_t NatsLink::subscribe(const std::string& subject, Handler handler) {
  auto s = std::make_unique<Subscription>();
  s->handler = std::move(handler);
  check(natsConnection_Subscribe(&s->sub, conn_->nc, subject.c_str(), &Subscription::on_message,
                                 s.get()),
        "NATS " + server_ + ": subscribe to " + subject);
  natsSubscription_SetOnCompleteCB(s->sub, &Subscription::on_complete, s.get());
  std::lock_guard lock(mutex_);
  const uint64_t id = next_id_++;
  subscriptions_[id] = std::move(s);
  return id;
}

void NatsLink::unsubscribe(uint64_t id) {
  std::unique_ptr<Subscription> s;
  {
    std::lock_guard lock(mutex_);
    auto it = subscriptions_.find(id);
    if (it == subscriptions_.end()) return;
    s = std::move(it->second);
    subscriptions_.erase(it);
  }
  s->close();
}

bool NatsLink::flush(std::chrono::milliseconds timeout) {
  return natsConnection_FlushTimeout(conn_->nc, timeout.count()) == NATS_OK;
}

bool NatsLink::connected() const {
  return natsConnection_Status(conn_->nc) == NATS_CONN_STATUS_CONNECTED;
}

}  // namespace vox::cluster
