// What the pipeline keeps of the rollbacks in flight (pipeline/rollbacks.hpp): the chunks
// being recomputed, which edits must not reach (frozen by a RollbackTask, thawed by one or
// as each slice of recomputed chunks lands), and whether a rollback's record is durable
// while slices are still to come (then no checkpoint may start: it would cover a record
// whose chunks are not all in place). Pipeline thread only.
#pragma once

#include <unordered_set>

#include "server/pipeline/edit_batch.hpp"
#include "server/world/chunk_coord.hpp"

namespace vox::pipeline {

class LodStage;

class RollbackSlices {
 public:
  using CoordSet = std::unordered_set<world::ChunkCoord, world::ChunkCoordHash>;

  // The frozen chunks, for the edit pass (EditRules::frozen) to add to, take from and check.
  CoordSet* frozen() { return &frozen_; }
  // False while a rollback's record is durable and more of its slices are to come.
  bool checkpoints_allowed() const { return !hold_checkpoints_; }
  // A batch is answered (`durable`, or undone): its rollback slices put in place for good
  // thaw their chunks, have the coarse levels re-mesh them and are answered.
  void answer(EditBatch& b, bool durable, LodStage& lod);

 private:
  CoordSet frozen_;
  bool hold_checkpoints_ = false;
};

}  // namespace vox::pipeline
