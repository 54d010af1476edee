// A gateway's forwarded edits (server/cluster/edit_forwarder.hpp) against a real
// nats-server the test starts: a zone moving between nodes is waited for (asked again),
// an answer arrives once; a holder that never answers, or a zone still moving at the
// timeout, is refused in time.
#include "server/cluster/edit_forwarder.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <memory>
#include <thread>

#include "server/cluster/zone_wire.hpp"
#include "tests/nats_server.hpp"

namespace vox::cluster {
namespace {

using std::chrono::milliseconds;

NatsConfig config_for(const test::NatsServer& server, const std::string& name) {
  return {.url = server.url(),
          .user = test::NatsServer::kUser,
          .password = test::NatsServer::kPassword,
          .name = name};
}

EditRequest a_request() {
  EditRequest r;
  r.author = "p";
  r.edit_id = 5;
  r.edit = world::Brush{{1.0f, 2.0f, 3.0f}, 3.0f, 1.0f, false, 2};
  return r;
}

struct Outcome {
  std::promise<EditReply> promise;
  std::future<EditReply> future = promise.get_future();
  EditForwarder::Done done() {
    return [this](const EditReply& r) { promise.set_value(r); };
  }
};

// A holder answering the zone's edit subject: "moving" its first `moving` times, then
// accepted.
struct Holder {
  Holder(NatsLink& link, world::ZoneId zone, int moving) : link(link) {
    subscription =
        link.subscribe(zone_subject("w", zone, "edit"), [this, moving](const NatsMessage& m) {
          const auto request = decode_edit_request(m.data);
          EditReply r;
          r.id = request ? request->id : 0;
          if (asked++ < moving) {
            r.reason = world::RefusalReason::kStorageUnavailable;
            r.zone_moving = true;
            r.message = "being loaded";
          }
          this->link.publish(m.reply, encode_edit_reply(r));
        });
    link.flush(milliseconds(2000));
  }
  NatsLink& link;
  uint64_t subscription = 0;
  std::atomic<int> asked{0};
};

TEST(EditForwarder, AZoneMovingBetweenNodesIsAskedAgainUntilItsHolderTakesTheEdit) {
  test::NatsServer server;
  NatsLink gateway_link(config_for(server, "gateway")), holder_link(config_for(server, "holder"));
  std::atomic<int> takes{0};
  EditForwarder forwarder(gateway_link, {.world = "w", .timeout = milliseconds(3000)},
                          [&](world::ZoneId) { ++takes; });
  // Nobody holds zone (1, 1) at first: asked again until a holder appears (it is loading
  // the zone for its first two answers).
  Outcome first;
  forwarder.forward({1, 1}, a_request(), first.done());
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_GE(takes.load(), 1) << "nobody was asked to take the zone";
  Holder holder(holder_link, {1, 1}, 2);
  ASSERT_EQ(first.future.wait_for(milliseconds(2500)), std::future_status::ready);
  const EditReply r = first.future.get();
  EXPECT_EQ(r.reason, world::RefusalReason::kNone) << r.message;
  EXPECT_EQ(holder.asked.load(), 3);
  EXPECT_GE(forwarder.retried(), 3u);
  EXPECT_EQ(forwarder.timed_out(), 0u);
}

TEST(EditForwarder, AZoneStillMovingAtTheTimeoutIsRefusedAsItsHolderSaid) {
  test::NatsServer server;
  NatsLink gateway_link(config_for(server, "gateway")), holder_link(config_for(server, "holder"));
  EditForwarder forwarder(gateway_link, {.world = "w", .timeout = milliseconds(400)},
                          [](world::ZoneId) {});
  Holder holder(holder_link, {2, 2}, 1000);  // loading for ever
  Outcome moving;
  const auto start = std::chrono::steady_clock::now();
  forwarder.forward({2, 2}, a_request(), moving.done());
  ASSERT_EQ(moving.future.wait_for(milliseconds(2000)), std::future_status::ready);
  EXPECT_LT(std::chrono::steady_clock::now() - start, milliseconds(1500));
  const EditReply r = moving.future.get();
  EXPECT_EQ(r.reason, world::RefusalReason::kStorageUnavailable);
  EXPECT_EQ(r.message, "being loaded");
  EXPECT_EQ(forwarder.timed_out(), 0u) << "a moving zone is not a silent holder";
  // A holder that never answers: refused at the timeout, saying it may have landed.
  holder_link.subscribe(zone_subject("w", {3, 3}, "edit"), [](const NatsMessage&) {});
  holder_link.flush(milliseconds(2000));
  Outcome silent;
  forwarder.forward({3, 3}, a_request(), silent.done());
  ASSERT_EQ(silent.future.wait_for(milliseconds(2000)), std::future_status::ready);
  EXPECT_NE(silent.future.get().message.find("may have been applied"), std::string::npos);
  EXPECT_EQ(forwarder.timed_out(), 1u);
}

}  // namespace
}  // namespace vox::cluster
