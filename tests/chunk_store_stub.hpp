// A world store for the pipeline parts' tests: its chunks, logged edits and info are what
// the test puts there; reads throw while it is "down", checkpoints while they fail.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "server/store/world_store.hpp"

namespace vox::test {

class ChunkStore final : public store::WorldStore {
 public:
  const std::string& name() const override { return name_; }
  store::WorldInfo info() override { return world_info; }
  void append_edits(std::span<const store::LoggedEdit>, std::span<const SeqRange>,
                    const store::RegionWrite*) override {}
  store::RegionTable read_regions() override { return {}; }
  void write_checkpoint(std::span<const store::ChunkRecord> records, uint64_t seq,
                        store::LogTrim trim) override {
    if (fail_checkpoints) throw store::StoreError("test: disk full");
    for (const store::ChunkRecord& r : records) chunks[r.coord] = r.samples;
    checkpoint_seq = seq;
    trimmed_through = trim.through;
    trimmed_before_ms = trim.accepted_before_ms;
  }
  std::optional<store::ChunkRecord> read_chunk(world::ChunkCoord c) override {
    ++reads;
    if (down) throw store::StoreError("test: database unreachable");
    auto it = chunks.find(c);
    if (it == chunks.end()) return std::nullopt;
    return store::ChunkRecord{c, 1, it->second};
  }
  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>& fn) override {
    for (const auto& [c, samples] : chunks) fn(c, 1);
  }
  void for_each_edit(uint64_t after,
                     const std::function<bool(const store::LoggedEdit&)>& fn) override {
    for (const store::LoggedEdit& e : logged) {
      if (e.seq > after && !fn(e)) return;
    }
  }

  std::map<world::ChunkCoord, std::vector<uint8_t>> chunks;
  std::vector<store::LoggedEdit> logged;
  store::WorldInfo world_info;
  bool down = false, fail_checkpoints = false;
  int reads = 0;
  uint64_t checkpoint_seq = 0, trimmed_through = 0;
  int64_t trimmed_before_ms = 0;

 private:
  std::string name_ = "test store";
};

inline world::Chunk rock() { return world::Chunk(world::Sample{1000, 3}); }

}  // namespace vox::test
