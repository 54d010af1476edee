// A real world store whose appends (or checkpoints) wait at a gate the test opens, and
// that can be made to fail: what holds an append in flight in the pipelined-commit tests.
#pragma once

#include <atomic>
#include <chrono>
#include <climits>
#include <condition_variable>
#include <mutex>

#include "server/store/world_store.hpp"

namespace vox::test {

// A real store whose appends (or checkpoints) wait at a gate the test opens; counts the
// calls that reached it.
class GatedStore final : public store::WorldStore {
 public:
  explicit GatedStore(store::WorldStore& inner, bool gate_checkpoints = false)
      : inner_(inner), gate_checkpoints_(gate_checkpoints) {}
  const std::string& name() const override { return inner_.name(); }
  store::WorldInfo info() override { return inner_.info(); }
  void append_edits(std::span<const store::LoggedEdit> edits, std::span<const SeqRange> forget,
                    const store::RegionWrite* regions) override {
    if (!gate_checkpoints_) pass_gate();
    if (failing_ || entered() >= fail_from_) throw store::StoreError("test: the disk is full");
    inner_.append_edits(edits, forget, regions);
    if (fail_after_write_) throw store::StoreError("test: the connection dropped at COMMIT");
  }
  store::RegionTable read_regions() override { return inner_.read_regions(); }
  void write_checkpoint(std::span<const store::ChunkRecord> chunks, uint64_t seq,
                        store::LogTrim trim) override {
    if (gate_checkpoints_) pass_gate();
    inner_.write_checkpoint(chunks, seq, trim);
  }
  std::optional<store::ChunkRecord> read_chunk(world::ChunkCoord c) override {
    return inner_.read_chunk(c);
  }
  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>& fn) override {
    inner_.for_each_chunk(fn);
  }
  void for_each_edit(uint64_t after,
                     const std::function<bool(const store::LoggedEdit&)>& fn) override {
    inner_.for_each_edit(after, fn);
  }
  void for_each_edit_back(uint64_t after, uint64_t through,
                          const std::function<bool(const store::LoggedEdit&)>& fn) override {
    inner_.for_each_edit_back(after, through, fn);
  }
  void for_each_rollback(uint64_t after,
                         const std::function<bool(const store::LoggedEdit&)>& fn) override {
    inner_.for_each_rollback(after, fn);
  }
  std::optional<store::ChunkRecord> read_base_chunk(world::ChunkCoord c) override {
    return inner_.read_base_chunk(c);
  }
  void advance_base(std::span<const store::ChunkRecord> chunks, uint64_t through) override {
    inner_.advance_base(chunks, through);
  }
  void reset_base() override { inner_.reset_base(); }

  void close() {
    std::lock_guard lock(mutex_);
    open_ = false;
  }
  void open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    cv_.notify_all();
  }
  void set_failing(bool failing) { failing_ = failing; }  // appends throw after the gate
  void set_failing_from(int n) { fail_from_ = n; }        // the n-th append to reach the gate on
  // Appends land, then throw: their outcome is in doubt for the pipeline.
  void set_fail_after_write(bool fail) { fail_after_write_ = fail; }
  int entered() {
    std::lock_guard lock(mutex_);
    return entered_;
  }
  // Waits (up to 10 s) until `n` appends have reached the gate.
  bool wait_entered(int n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return entered_ >= n; });
  }

 private:
  void pass_gate() {
    std::unique_lock lock(mutex_);
    ++entered_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
  }

  store::WorldStore& inner_;
  const bool gate_checkpoints_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = true;
  int entered_ = 0;
  std::atomic<bool> failing_{false}, fail_after_write_{false};
  std::atomic<int> fail_from_{INT_MAX};
};

}  // namespace vox::test
