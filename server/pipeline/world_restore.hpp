// The world as the store has it, at start: the checkpointed chunks known (read when first
// needed), the protected regions, then the log after the checkpoint replayed in order,
// exactly as the batches applied it (so the densities are bit-identical). The chunks the
// replay changed are unsaved: the next checkpoint writes them. Pipeline's constructor,
// before its thread starts.
#pragma once

#include <cstdint>

#include "server/pipeline/edit_step.hpp"
#include "server/store/world_store.hpp"

namespace vox::pipeline {

class ProtectedRegions;
class StoredChunkReader;

struct RestoredWorld {
  store::WorldInfo info;
  uint64_t replayed = 0;   // logged edits applied again
  uint64_t rollbacks = 0;  // rollback records among them (store/world_history.hpp)
  uint64_t next_seq = 1;   // the next edit's sequence number
};

// Throws store::StoreError when the store cannot be read, a chunk it names is damaged, or a
// logged edit cannot be applied again (`reader`'s error, or the refusal, in the message).
RestoredWorld restore_world(store::WorldStore& store, EditWorld& world, ProtectedRegions& regions,
                            const StoredChunkReader& reader);

}  // namespace vox::pipeline
