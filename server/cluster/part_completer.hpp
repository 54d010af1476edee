// Completes the parts of edits across zones that this node's zones' logs still miss
// (docs/CLUSTER.md, "Edits across a border"): when one node logs its part of such an
// edit, the other parts go to `zone_pending` in the same transaction. Their own requests
// normally land soon after and remove them; one whose holder died, stalled or refused
// it is left. Every couple of seconds this reads those of the zones the node holds that
// are older than `age`, and submits each as a part of its edit (its edit id makes a
// second arrival harmless: ZoneTable::has_edit, and the log's own check in read_pending),
// applied as the holder that logged the edit recorded it: the samples it kept (its
// protected regions then), not clipped again. The edit was accepted, so its part must
// land: a region added since must not refuse it for ever. A part refused as never
// applicable (a damaged row that still decodes into an invalid edit) is removed, with an
// error line; one refused for now (store, memory) is tried again.
//
// Threads: its own ("vox-parts"); construct and stop on one thread. `submit` and
// `writable` are called on its thread; a submitted part's answer on the pipeline thread.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "server/pipeline/edit_batch.hpp"
#include "server/store/zone_leases.hpp"

namespace vox::cluster {

class PartCompleter {
 public:
  using Submit = std::function<void(pipeline::EditTask task)>;
  using Writable = std::function<std::vector<world::ZoneId>()>;
  struct Config {
    std::string uri, node;
    std::chrono::milliseconds lease{3000};
    std::chrono::milliseconds age{5000};    // a pending part younger than this is left
    std::chrono::milliseconds every{2000};  // how often pending parts are read
    size_t max_in_flight = 256;             // parts submitted and not answered yet
  };
  PartCompleter(Config config, Writable writable, Submit submit);
  ~PartCompleter();  // stop()
  PartCompleter(const PartCompleter&) = delete;
  PartCompleter& operator=(const PartCompleter&) = delete;
  void stop();  // idempotent; parts still in the pipeline answer later, to nobody

  uint64_t completed() const { return completed_.load(std::memory_order_relaxed); }  // any thread

 private:
  void run();
  void sweep();

  const Config config_;
  const Writable writable_;
  const Submit submit_;
  store::ZoneLeases db_;  // this thread's connection
  std::mutex mutex_;      // guards stop_, in_flight_, to_drop_ (leaf)
  std::condition_variable wake_;
  bool stop_ = false;
  std::set<std::pair<world::ZoneId, uint64_t>> in_flight_;  // (zone, edit id) submitted
  // Parts refused as never applicable: removed from zone_pending at the next sweep (on
  // this thread's connection); at most max_in_flight.
  std::set<std::pair<world::ZoneId, uint64_t>> to_drop_;
  std::atomic<uint64_t> completed_{0};
  std::thread thread_;
};

}  // namespace vox::cluster
