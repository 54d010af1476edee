#include "server/pipeline/batch_scheduler.hpp"

#include <algorithm>

namespace vox::pipeline {

using world::ChunkCoord;

void BatchScheduler::add(OrderedTask task) { ordered_.push_back(std::move(task)); }

std::function<void()> BatchScheduler::request(LoadOwner owner, std::vector<ChunkCoord> chunks,
                                              std::function<void()> done, uint64_t budget_group) {
  auto [it, inserted] = requests_.try_emplace(owner);
  Request& r = it->second;
  std::function<void()> replaced = std::move(r.done);
  queued_chunks_ -= r.chunks.size() - r.next;
  r = Request{std::move(chunks), 0, std::move(done), budget_group};
  queued_chunks_ += r.chunks.size();
  // A replaced request keeps its owner's place in the rotation.
  if (inserted) rotation_.push_back(owner);
  return replaced;
}

std::function<void()> BatchScheduler::drop(LoadOwner owner, Clock::time_point now) {
  if (auto b = budgets_.find(owner); b != budgets_.end()) {
    if (auto g = groups_.find(b->second.group); g != groups_.end()) --g->second.owners;
    budgets_.erase(b);
    purge_groups(now);
  }
  auto it = requests_.find(owner);
  if (it == requests_.end()) return {};
  std::function<void()> done = std::move(it->second.done);
  queued_chunks_ -= it->second.chunks.size() - it->second.next;
  requests_.erase(it);
  rotation_.erase(std::find(rotation_.begin(), rotation_.end(), owner));
  return done;
}

std::vector<OrderedTask> BatchScheduler::take_ordered() {
  std::vector<OrderedTask> all(std::make_move_iterator(ordered_.begin()),
                               std::make_move_iterator(ordered_.end()));
  ordered_.clear();
  return all;
}

// Created on first use, while the owner has a request (which names its group).
BatchScheduler::OwnerBudget& BatchScheduler::budget_of(LoadOwner owner, Clock::time_point now) {
  auto [it, inserted] =
      budgets_.try_emplace(owner, OwnerBudget{TokenBucket(owner_rate_, owner_burst_, now), 0});
  const auto r = requests_.find(owner);
  const uint64_t group = r == requests_.end() ? 0 : r->second.group;
  if (inserted && group != 0 && group_rate_ > 0) {
    it->second.group = group;
    ++groups_.try_emplace(group, GroupBudget{TokenBucket(group_rate_, group_burst_, now), 0})
          .first->second.owners;
  }
  return it->second;
}

bool BatchScheduler::ready(LoadOwner owner, Clock::time_point now) {
  if (owner & kUnlimitedOwners) return true;
  OwnerBudget& b = budget_of(owner, now);
  if (b.bucket.wait_for(1, now).count() > 0) return false;
  auto g = groups_.find(b.group);
  return g == groups_.end() || g->second.bucket.wait_for(1, now).count() == 0;
}

void BatchScheduler::charge(LoadOwner owner, double work, Clock::time_point now) {
  if (owner & kUnlimitedOwners) return;
  OwnerBudget& b = budget_of(owner, now);
  b.bucket.charge(work, now);
  if (auto g = groups_.find(b.group); g != groups_.end()) g->second.bucket.charge(work, now);
}

void BatchScheduler::purge_groups(Clock::time_point now) {
  for (auto it = groups_.begin(); it != groups_.end();) {
    GroupBudget& g = it->second;
    it = g.owners == 0 && g.bucket.tokens(now) >= g.bucket.burst() ? groups_.erase(it)
                                                                   : std::next(it);
  }
}

bool BatchScheduler::has_ready_loads(Clock::time_point now) {
  for (LoadOwner owner : rotation_) {
    if (ready(owner, now)) return true;
  }
  return false;
}

void BatchScheduler::take_from(LoadOwner owner, size_t max_chunks, const Cost& cost,
                               Clock::time_point now, const std::function<bool()>& more,
                               Pass& pass) {
  Request& r = requests_.at(owner);
  const auto [at, fresh] = pass.at.try_emplace(owner, pass.loads.size());
  if (fresh) pass.loads.push_back(LoadSlice{owner, {}, {}});
  LoadSlice& slice = pass.loads[at->second];  // the round robin goes on from the first part
  size_t taken = 0;
  while (r.next < r.chunks.size() && taken < max_chunks && more()) {
    const ChunkCoord c = r.chunks[r.next++];
    --queued_chunks_;
    ++pass.scanned;
    const size_t work = cost(c);
    if (work == 0) continue;  // nothing to do: costs no turn
    slice.chunks.push_back(c);
    ++taken;
    pass.spent += work;
    charge(owner, static_cast<double>(work), now);
    if (!ready(owner, now)) break;  // its budget is spent
  }
  if (r.next == r.chunks.size()) {
    slice.done = std::move(r.done);
    requests_.erase(owner);
    rotation_.erase(std::find(rotation_.begin(), rotation_.end(), owner));
  }
}

std::vector<LoadSlice> BatchScheduler::take_loads(size_t load_budget, const Cost& cost,
                                                  size_t scan_limit, Clock::time_point now) {
  Pass pass;
  // Fewest chunks left first, within the share (ties: the older owner, the lower id).
  const auto share = static_cast<size_t>(static_cast<double>(load_budget) * kShortestFirstShare);
  std::vector<std::pair<size_t, LoadOwner>> shortest;
  shortest.reserve(rotation_.size());
  for (const LoadOwner owner : rotation_) {
    const Request& r = requests_.at(owner);
    shortest.emplace_back(r.chunks.size() - r.next, owner);
  }
  std::sort(shortest.begin(), shortest.end());
  const auto within_share = [&] { return pass.spent < share && pass.scanned < scan_limit; };
  for (const auto& [left, owner] : shortest) {
    if (!within_share()) break;
    if (ready(owner, now)) take_from(owner, SIZE_MAX, cost, now, within_share, pass);
  }
  // Then round robin. Owners out of budget are passed over (they keep their place); the
  // pass ends when a whole round finds no owner with budget.
  const auto within_budget = [&] { return pass.spent < load_budget && pass.scanned < scan_limit; };
  size_t passed_over = 0;
  while (within_budget() && passed_over < rotation_.size()) {
    const LoadOwner owner = rotation_.front();
    rotation_.pop_front();
    rotation_.push_back(owner);  // take_from takes it out again if its request finishes
    if (!ready(owner, now)) {
      ++passed_over;
      continue;
    }
    passed_over = 0;
    take_from(owner, group_, cost, now, within_budget, pass);
  }
  // Owners looked at whose chunks all cost nothing and whose request goes on: no slice.
  std::erase_if(pass.loads, [](const LoadSlice& l) { return l.chunks.empty() && !l.done; });
  return std::move(pass.loads);
}

std::vector<std::function<void()>> BatchScheduler::take_all_load_callbacks() {
  std::vector<std::function<void()>> all;
  for (auto& [owner, r] : requests_) {
    if (r.done) all.push_back(std::move(r.done));
  }
  requests_.clear();
  rotation_.clear();
  queued_chunks_ = 0;
  return all;
}

namespace {

// Sorts nearest `twice_center / 2` first; ties by coordinate (a total order, so std::sort
// is deterministic).
void sort_nearest_first(std::vector<ChunkCoord>& chunks, int64_t cx2, int64_t cy2, int64_t cz2) {
  auto distance2 = [&](const ChunkCoord& c) {
    const int64_t dx = 2 * int64_t{c.x} - cx2, dy = 2 * int64_t{c.y} - cy2,
                  dz = 2 * int64_t{c.z} - cz2;
    return dx * dx + dy * dy + dz * dz;
  };
  std::sort(chunks.begin(), chunks.end(), [&](const ChunkCoord& a, const ChunkCoord& b) {
    const int64_t da = distance2(a), db = distance2(b);
    return da != db ? da < db : a < b;
  });
}

}  // namespace

std::vector<ChunkCoord> ball_nearest_first(ChunkCoord center, int radius) {
  std::vector<ChunkCoord> chunks;
  const int64_t r2 = int64_t{radius} * radius;
  for (int dz = -radius; dz <= radius; ++dz)
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        if (int64_t{dx} * dx + int64_t{dy} * dy + int64_t{dz} * dz <= r2)
          chunks.push_back(center.offset(dx, dy, dz));
      }
  sort_nearest_first(chunks, 2 * int64_t{center.x}, 2 * int64_t{center.y}, 2 * int64_t{center.z});
  return chunks;
}

std::vector<ChunkCoord> box_nearest_first(ChunkCoord lo, ChunkCoord hi) {
  std::vector<ChunkCoord> chunks;
  world::for_each_chunk_in(lo, hi, [&chunks](ChunkCoord c) { chunks.push_back(c); });
  sort_nearest_first(chunks, int64_t{lo.x} + hi.x, int64_t{lo.y} + hi.y, int64_t{lo.z} + hi.z);
  return chunks;
}

}  // namespace vox::pipeline
