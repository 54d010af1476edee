// A query about the samples (QueryTask) answered in its place among the batch's tasks, on
// the world as the edits before it left it: the ray or box read through the chunks in
// memory, those missing loaded (or generated) as the query reaches them. Queries share a
// budget of the pipeline thread's time and of chunk loads (QueryBudget), so that however
// many clients ask, the edits of every player keep most of the thread. Pipeline thread
// only.
#pragma once

#include "server/pipeline/batch_scheduler.hpp"
#include "server/pipeline/edit_step.hpp"
#include "server/pipeline/token_bucket.hpp"

namespace vox::pipeline {

// What all queries together may take: seconds of the pipeline thread (charged after each
// query, so one long query may overdraw it) and chunks loaded. Pipeline thread only.
struct QueryBudget {
  TokenBucket seconds{0.1, 0.05};  // a tenth of the thread, 50 ms at once
  TokenBucket loads{200, 64};      // chunks loaded or generated per second
  static constexpr size_t kLoadsPerQuery = 16;
};

// Answers `task` (its done() is called once, then dropped); without a budget, unlimited.
void answer_query(QueryTask& task, EditWorld& world, QueryBudget* budget, Clock::time_point now);

}  // namespace vox::pipeline
