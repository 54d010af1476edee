// One hostile connection of --attack, beside the honest players on the same event loop.
// Its socket and timer live on its own strand (every private member runs there only);
// whatever the server does to it (refuse, close, reset) is counted in the load test's
// AttackTally and answered by connecting again after a short pause, until stop().
//
// Kinds (AttackKind):
//   flood  Hello, then every 20 ms a SetView of radius max_view_radius at a random place up
//          to 100k voxels out; even-numbered flooders (so flood:1 has one) also leave after
//          2..5 s and come back at once on a fresh connection (burst, then disconnect).
//   heavy  Hello, then keeps max_edits_in_flight box Stamps of side 2*max_edit_radius in
//          flight (far away, a quarter at one spot among the players); ignores
//          retry_after_ms, as a hostile client would.
//   squat  one socket of a group of kSquatGroupSize: the first half of each group never
//          sends a byte, the second half says Hello and then pings every 10 s.
//   slow   Hello, a SetView of radius max_view_radius among the players, then never reads
//          again (a 4 KiB receive buffer); it sees the server close it through TCP_INFO
//          and through its pings failing.
//   empty  Hello, then empty frames (a zero length is an empty Envelope) as fast as the
//          socket takes them, reading and counting what comes back.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <random>
#include <span>
#include <vector>

#include "client/asio.hpp"
#include "loadtest/attack_mix.hpp"
#include "loadtest/attack_stats.hpp"
#include "proto/framing.hpp"
#include "voxel.pb.h"

namespace vox::loadtest {

class LoadTest;

class Attacker : public std::enable_shared_from_this<Attacker> {
 public:
  // `index` counts within the kind (squatters: sockets, not groups).
  Attacker(LoadTest& test, AttackKind kind, int index, uint32_t seed);
  void start();  // any thread: connect and attack until stop()
  void stop();   // any thread: close for good; no reconnect after it

 private:
  void connect();
  void on_connected();
  void read_more();
  void on_frame(std::span<const uint8_t> body);
  void on_welcome(const wire::Welcome& w);
  // Closes the connection and connects again after `pause_s`; `by_server` counts it
  // as a disconnect the server made.
  void lost(bool by_server, double pause_s);
  void arm_timer(double seconds);
  void on_timer();
  bool send(const wire::Envelope& m);  // false: dropped, the outbox is full
  void write_more();
  void write_empty_frames();
  bool silent() const;  // a squatter that never says Hello

  void flood_step();
  void heavy_step();
  void slow_step();
  void squat_step();
  wire::Envelope heavy_stamp();
  wire::Envelope view_at(const std::array<float, 3>& at) const;
  std::array<float, 3> far_place();
  double now_s() const;

  LoadTest& test_;
  AttackTally& tally_;
  const AttackKind kind_;
  const int index_;
  std::mt19937 rng_;
  boost::asio::strand<boost::asio::io_context::executor_type> strand_;
  boost::asio::ip::tcp::socket socket_;
  boost::asio::steady_timer timer_;
  proto::FrameDecoder decoder_;
  std::array<uint8_t, 16 * 1024> buffer_;
  // Frames wait in outbox_ (bounded: kMaxOutboxBytes, more are dropped and counted) while
  // in_write_ is on the wire.
  std::vector<uint8_t> outbox_, in_write_;
  bool writing_ = false, open_ = false, welcomed_ = false, stopped_ = false;
  // Bumped by every close: handlers of an older connection find it changed and do nothing.
  uint64_t connection_ = 0;

  uint32_t max_view_radius_ = 0, max_in_flight_ = 0;
  float max_edit_radius_ = 0;
  uint32_t in_flight_ = 0;  // heavy: edits sent on this connection without a result yet
  uint64_t next_request_ = 1;
  double leave_at_s_ = 0;  // flood: when a reconnecting flooder drops its connection
  double next_ping_s_ = 0;
  std::array<float, 3> spot_{};  // heavy: the one place among the players it keeps hitting
};

}  // namespace vox::loadtest
