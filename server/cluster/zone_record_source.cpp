#include "server/cluster/zone_record_source.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/cluster/zone_follower.hpp"
#include "server/cluster/zone_wire.hpp"

namespace vox::cluster {
namespace {

// Records one read hands the pipeline at most: it goes on between reads.
constexpr size_t kRecordsPerRead = 2000;
// Zones whose checkpoint could not be installed, remembered (a bound: forgotten all at once).
constexpr size_t kMaxUnusable = 1024;

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

// Records of a zone this node does not hold, after record `applied`.
pipeline::ZoneRecords followed(world::ZoneId zone, uint64_t applied) {
  return {.zone = zone,
          .epoch = 0,
          .fresh = false,
          .checkpoint = std::nullopt,
          .edits = {},
          .through = applied};
}

}  // namespace

ZoneRecordSource::ZoneRecordSource(ZoneTable& table, ZoneReplicas& replicas,
                                   ZonePublisher& publisher, store::ZoneLeases& db,
                                   std::string store_name)
    : table_(table),
      replicas_(replicas),
      publisher_(publisher),
      db_(db),
      store_name_(std::move(store_name)) {}

std::optional<pipeline::ZoneRecords> ZoneRecordSource::next() {
  if (const std::optional<world::ZoneId> zone = table_.next_fresh()) return fresh_records(*zone);
  // Taken zones' logs and followed zones' records in turn: a zone whose records cannot be
  // applied now must not hold up the others.
  catch_up_first_ = !catch_up_first_;
  if (catch_up_first_) {
    if (auto records = catch_up()) return records;
    return followed_records();
  }
  if (auto records = followed_records()) return records;
  return catch_up();
}

// Decodes `records` into out.edits while each follows the one before (out.through is the
// last record before them); stops at a gap. Returns how many were used.
size_t ZoneRecordSource::append_run(world::ZoneId zone,
                                    const std::vector<store::ZoneRecord>& records,
                                    pipeline::ZoneRecords& out, uint64_t last) const {
  size_t used = 0;
  for (const store::ZoneRecord& r : records) {
    if (r.seq > last || r.seq != out.through + 1) break;
    std::string why;
    std::optional<store::LoggedEdit> e = decode_zone_edit(r, &why);
    if (!e)
      throw store::StoreError(store_name_ + ": " + describe(zone) + " record " +
                              std::to_string(r.seq) + ": " + why);
    out.edits.push_back(std::move(*e));
    out.through = r.seq;
    ++used;
  }
  return used;
}

// The log read after what the world has must continue it: a record missing (a damaged
// database, or a migrated zone whose checkpoint could not be installed) stops the zone here.
void ZoneRecordSource::expect_next(world::ZoneId zone, const std::vector<store::ZoneRecord>& read,
                                   uint64_t after) const {
  if (!read.empty() && read.front().seq != after + 1)
    throw store::StoreError(store_name_ + ": " + describe(zone) + ": its log has no record " +
                            std::to_string(after + 1) + " (it goes on at " +
                            std::to_string(read.front().seq) + ")");
}

// A held zone's log after what the world has (a zone just taken, or an append in doubt).
std::optional<pipeline::ZoneRecords> ZoneRecordSource::catch_up() {
  for (;;) {
    // Zones take turns (one whose log cannot be read or applied holds up no other).
    const std::optional<ZoneTable::CatchUp> c = table_.next_catch_up(caught_up_last_);
    if (!c) return std::nullopt;
    caught_up_last_ = c->zone;
    const std::optional<store::ZoneRow> row = db_.read(c->zone);
    if (!row || row->epoch != c->epoch) {  // taken by another node meanwhile
      table_.lost(c->zone, c->epoch);
      continue;
    }
    if (row->checkpoint_seq > row->last_seq)
      throw store::StoreError(store_name_ + ": " + describe(c->zone) + ": its checkpoint (record " +
                              std::to_string(row->checkpoint_seq) + ") is past its log's end (" +
                              std::to_string(row->last_seq) + ")");
    targets_[c->zone] = row->last_seq;
    pipeline::ZoneRecords out{.zone = c->zone,
                              .epoch = c->epoch,
                              .fresh = false,
                              .checkpoint = std::nullopt,
                              .edits = {},
                              .through = c->applied};
    if (row->last_seq <= c->applied) return out;
    out.checkpoint = checkpoint_past(c->zone, c->applied, row->checkpoint_seq);
    if (out.checkpoint) out.through = out.checkpoint->seq;
    const std::vector<store::ZoneRecord> read = db_.read_log(c->zone, out.through, kRecordsPerRead);
    expect_next(c->zone, read, out.through);
    append_run(c->zone, read, out, row->last_seq);
    return out;
  }
}

pipeline::ZoneRecords ZoneRecordSource::fresh_records(world::ZoneId zone) {
  handed_.clear();
  pipeline::ZoneRecords out = followed(zone, 0);
  out.fresh = true;
  // Held or followed: its checkpoint replaces the chunks it lists at once (its viewers do
  // not see them generated meanwhile); its log follows by its catch-up or its follower.
  // Neither, or the checkpoint cannot be read now (a zone that cannot be read must not
  // hold up the others): the world has none of its records.
  if (!table_.held(zone) && !replicas_.following(zone) && !replicas_.viewed_lately(zone))
    return out;
  try {
    if (const std::optional<store::ZoneRow> row = db_.read(zone))
      out.checkpoint = checkpoint_past(zone, 0, row->checkpoint_seq);
  } catch (const store::StoreError& e) {
    spdlog::warn(
        "cluster: {}: its checkpoint cannot be read ({}); its log is applied from the "
        "start",
        describe(zone), e.what());
  }
  if (out.checkpoint) out.through = out.checkpoint->seq;
  return out;
}

// Records of a followed zone, as its owner committed them.
std::optional<pipeline::ZoneRecords> ZoneRecordSource::followed_records() {
  // A zone followed anew whose checkpoint the world should install (its follower starts
  // after it): the checkpoint, or, when it cannot be installed, the log from what the
  // world has.
  std::vector<world::ZoneId> started = replicas_.take_started();
  // Zones take turns, from the one after the zone started last (one whose checkpoint or
  // log cannot be read or applied now holds up no other).
  if (started_last_) {
    std::rotate(started.begin(), std::upper_bound(started.begin(), started.end(), *started_last_),
                started.end());
  }
  for (size_t i = 0; i < started.size(); ++i) {
    const world::ZoneId zone = started[i];
    if (table_.held(zone)) continue;
    started_last_ = zone;
    try {
      const auto [applied, fresh] = table_.position(zone);
      if (fresh) {  // forgotten first (next())
        replicas_.started_again(zone);
        continue;
      }
      const std::optional<store::ZoneRow> row = db_.read(zone);
      if (!row || !checkpoint_first(applied, row->checkpoint_seq)) continue;
      pipeline::ZoneRecords out = followed(zone, applied);
      out.checkpoint = checkpoint_past(zone, applied, row->checkpoint_seq);
      if (out.checkpoint) out.through = out.checkpoint->seq;
      const std::vector<store::ZoneRecord> read = db_.read_log(zone, out.through, kRecordsPerRead);
      expect_next(zone, read, out.through);
      append_run(zone, read, out, UINT64_MAX);
      if (!out.checkpoint && out.edits.empty()) continue;
      for (size_t j = i + 1; j < started.size(); ++j) replicas_.started_again(started[j]);
      handed_.clear();
      return out;
    } catch (const store::StoreError&) {
      for (size_t j = i; j < started.size(); ++j) replicas_.started_again(started[j]);
      throw;
    }
  }
  std::optional<ZoneReplicas::Taken> taken = replicas_.take(
      kRecordsPerRead, [this](world::ZoneId z) { return table_.held(z); },
      [this](world::ZoneId z) { return table_.applied(z); });
  if (!taken) return std::nullopt;
  const world::ZoneId zone = taken->zone;
  const auto [applied, fresh] = table_.position(zone);
  if (fresh) {  // forgotten first (next())
    replicas_.give_back(zone, std::move(taken->records));
    return std::nullopt;
  }
  pipeline::ZoneRecords out = followed(zone, applied);
  if (taken->records.front().seq != applied + 1) {
    // Not the next record (this node's world moved otherwise, or its follower started
    // after the zone's checkpoint): the checkpoint first if it should be installed, and
    // the log has the records between.
    try {
      if (const std::optional<store::ZoneRow> row = db_.read(zone))
        out.checkpoint = checkpoint_past(zone, applied, row->checkpoint_seq);
      if (out.checkpoint) out.through = out.checkpoint->seq;
      std::vector<store::ZoneRecord> read = db_.read_log(zone, out.through, kRecordsPerRead);
      expect_next(zone, read, out.through);
      taken->records = std::move(read);
    } catch (const store::StoreError&) {
      replicas_.give_back(zone, std::move(taken->records));
      throw;
    }
    if (taken->records.empty() && !out.checkpoint) return std::nullopt;
  }
  size_t used = 0;
  try {
    used = append_run(zone, taken->records, out, UINT64_MAX);
  } catch (const store::StoreError&) {
    replicas_.give_back(zone, std::move(taken->records));
    throw;
  }
  // Past a gap (records queued twice, or out of turn): taken again, in order, next time.
  if (used < taken->records.size()) {
    replicas_.give_back(zone,
                        {taken->records.begin() + static_cast<long>(used), taken->records.end()});
    taken->records.resize(used);
  }
  handed_ = std::move(taken->records);
  if (out.edits.empty() && !out.checkpoint) return std::nullopt;
  return out;
}

std::optional<store::ZoneCheckpoint> ZoneRecordSource::checkpoint_past(world::ZoneId zone,
                                                                       uint64_t applied,
                                                                       uint64_t checkpoint_seq) {
  if (!checkpoint_first(applied, checkpoint_seq)) return std::nullopt;
  // One that could not be installed is not read again: the log is applied instead.
  if (const auto bad = unusable_.find(zone);
      bad != unusable_.end() && bad->second == checkpoint_seq)
    return std::nullopt;
  std::optional<store::ZoneCheckpoint> cp = db_.read_checkpoint(zone, ZoneTable::kRememberedEdits);
  if (!cp || cp->seq <= applied) return std::nullopt;
  return cp;
}

void ZoneRecordSource::applied(const pipeline::ZoneRecords& records, uint64_t through) {
  if (records.fresh) {  // the world forgot what it had of the zone, then installed `through`
    const bool installed = records.checkpoint && through >= records.checkpoint->seq;
    if (records.checkpoint && !installed) {  // not read again (see below)
      if (unusable_.size() >= kMaxUnusable) unusable_.clear();
      unusable_[records.zone] = records.checkpoint->seq;
    }
    table_.reset(records.zone, installed ? through : 0);
    if (installed) {
      for (const uint64_t id : records.checkpoint->edit_ids) table_.note_edit(records.zone, id);
      installed_.fetch_add(1, std::memory_order_relaxed);
    }
    if (replicas_.following(records.zone)) replicas_.started_again(records.zone);
    return;
  }
  if (records.checkpoint && through < records.checkpoint->seq) {
    // Not installed (a chunk that does not decode, or lies outside the zone: the pipeline
    // said which): its log is applied instead, from what the world has.
    if (unusable_.size() >= kMaxUnusable) unusable_.clear();
    unusable_[records.zone] = records.checkpoint->seq;
    if (records.epoch == 0) replicas_.started_again(records.zone);
  }
  if (records.checkpoint && through >= records.checkpoint->seq) {
    for (const uint64_t id : records.checkpoint->edit_ids) table_.note_edit(records.zone, id);
    installed_.fetch_add(1, std::memory_order_relaxed);
    spdlog::info("cluster: {}: its checkpoint through record {} installed ({} chunks)",
                 describe(records.zone), records.checkpoint->seq,
                 records.checkpoint->chunks.size());
  }
  for (const store::LoggedEdit& e : records.edits) {
    if (e.seq <= through) table_.note_edit(records.zone, e.edit_id);
  }
  if (records.epoch == 0) {  // a followed zone's
    table_.committed(records.zone, through);
    std::erase_if(handed_, [&](const store::ZoneRecord& r) { return r.seq <= through; });
    if (!handed_.empty()) replicas_.give_back(records.zone, std::move(handed_));
    handed_.clear();
    return;
  }
  const auto it = targets_.find(records.zone);
  const bool complete = it != targets_.end() && through >= it->second;
  // A zone lost while its log was being applied is caught up afresh if taken again.
  if (it != targets_.end() && !complete && !table_.held(records.zone)) targets_.erase(it);
  if (complete) {
    // Its records continue from here; then edits in it are taken.
    publisher_.adopt(records.zone, through);
    targets_.erase(it);
  }
  table_.caught_up(records.zone, records.epoch, through, complete);
  if (complete && !table_.held(records.zone)) publisher_.forget(records.zone);
  if (complete && table_.writable(records.zone))
    spdlog::info("cluster: {} is writable here (its log applied through record {})",
                 describe(records.zone), through);
}

}  // namespace vox::cluster
