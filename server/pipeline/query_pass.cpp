#include "server/pipeline/query_pass.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "server/pipeline/world_state.hpp"

namespace vox::pipeline {

using world::ChunkCoord;

namespace {

constexpr const char* kStorageReadMessage =
    "a chunk this query reads cannot be read from the world store now (unreachable, or "
    "damaged); ask again later";

// The chunks of the world for a query: those not in memory are loaded, up to
// kLoadsPerQuery per query and as the budget's loads allow (then it gives up; the next
// query goes on from there).
class QuerySource final : public mesh::ChunkSource {
 public:
  QuerySource(EditWorld& world, QueryBudget* budget, Clock::time_point now)
      : world_(world), budget_(budget), now_(now) {}
  const world::Chunk* chunk(ChunkCoord c) override {
    WorldState& st = world_.state;
    if (const world::Chunk* found = st.chunks.find(c)) {
      st.info.at(c).last_used = now_;
      return found;
    }
    if (loads_ == QueryBudget::kLoadsPerQuery) {
      refused_ = world::RefusalReason::kOverBudget;
      message_ = "the query reaches more terrain not in memory than one query loads (" +
                 std::to_string(QueryBudget::kLoadsPerQuery) +
                 " chunks); those loaded stay: ask again";
      return nullptr;
    }
    if (const auto wait = budget_ ? budget_->loads.take(1, now_) : std::chrono::milliseconds(0);
        wait.count() > 0) {
      refused_ = world::RefusalReason::kServerBusy;
      retry_ms_ = static_cast<uint32_t>(std::min<int64_t>(wait.count(), 60000));
      message_ = "the server loads terrain for queries at a limited rate; ask again";
      return nullptr;
    }
    ++loads_;
    size_t generated = 0;
    refused_ = load_chunks(world_, {c}, 1, 0, now_, generated);
    if (refused_ == world::RefusalReason::kNone) return st.chunks.find(c);
    message_ = refused_ == world::RefusalReason::kServerBusy
                   ? "the server's memory budget is full: queries needing new terrain are "
                     "refused"
                   : kStorageReadMessage;
    return nullptr;
  }
  world::RefusalReason refused() const { return refused_; }
  uint32_t retry_ms() const { return retry_ms_; }
  std::string& message() { return message_; }

 private:
  EditWorld& world_;
  QueryBudget* budget_;
  const Clock::time_point now_;
  size_t loads_ = 0;
  world::RefusalReason refused_ = world::RefusalReason::kNone;
  uint32_t retry_ms_ = 0;
  std::string message_;
};

}  // namespace

void answer_query(QueryTask& task, EditWorld& world, QueryBudget* budget, Clock::time_point now) {
  QueryAnswer a;
  const auto start = Clock::now();
  if (const double left = budget ? budget->seconds.tokens(start) : 1; left <= 0) {
    a.reason = world::RefusalReason::kServerBusy;
    a.message = "queries have had their share of the server's time; ask again";
    a.retry_after_ms = static_cast<uint32_t>(
        std::min(60000.0, 1 + std::ceil(-left / budget->seconds.rate() * 1000)));
  } else {
    QuerySource source(world, budget, now);
    const bool complete = task.ray ? (a.hit = mesh::raycast(source, *task.ray)).complete
                                   : mesh::read_samples(source, task.box, a.densities, a.materials);
    if (!complete) {
      a.reason = source.refused(), a.message = std::move(source.message());
      a.retry_after_ms = source.retry_ms();
    }
    if (budget)
      budget->seconds.charge(std::chrono::duration<double>(Clock::now() - start).count(),
                             Clock::now());
  }
  auto done = std::move(task.done);  // not kept (nor the session it holds) with the batch
  if (done) done(a);
}

}  // namespace vox::pipeline
