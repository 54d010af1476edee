#include "server/store/zone_world.hpp"

#include <string>

#include "server/store/chunk_codec.hpp"
#include "server/world/edit_replay.hpp"
#include "server/world/terrain_generator.hpp"

namespace vox::store {
namespace {

std::string describe(world::ZoneId z) {
  return "zone (" + std::to_string(z.x) + ", " + std::to_string(z.z) + ")";
}

std::string describe(world::ChunkCoord c) {
  return "chunk (" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) +
         ")";
}

constexpr size_t kLogPage = 5000;

}  // namespace

ZoneWorld read_zone_world(ZoneLeases& db, bool verify, std::ostream& err) {
  ZoneWorld out;
  const std::optional<WorldSettings> settings = db.world_settings();
  if (!settings || settings->zone_chunks <= 0)
    throw StoreError("the database holds no cluster world");
  out.settings = *settings;
  const int size = out.settings.zone_chunks;
  const world::TerrainGenerator generator(out.settings.seed);
  world::EditLimits limits;
  limits.max_radius = limits.max_strength = 1e9f;  // the servers' limits may have been wider
  for (const world::ZoneId zone : db.zones()) {
    const std::optional<ZoneRow> row = db.read(zone);
    if (!row) continue;
    ++out.zones;
    const std::optional<ZoneCheckpoint> cp = db.read_checkpoint(zone, 0);
    const std::vector<ZoneRecord> first = db.read_log(zone, 0, 1);
    // A log from record 1 replays from the seed; else from the checkpoint it starts after.
    const bool from_seed = !first.empty() ? first.front().seq == 1 : !cp;
    if (!from_seed && !cp)
      throw StoreError(describe(zone) + ": its log starts at record " +
                       std::to_string(first.front().seq) + " and it has no checkpoint");
    const auto install = [&](const ZoneCheckpoint& c) {
      for (const ChunkRecord& r : c.chunks) {
        if (world::zone_of(r.coord, size) != zone)
          throw StoreError(describe(zone) + ": its checkpoint holds " + describe(r.coord) +
                           " of another zone");
        std::string why;
        std::optional<world::Chunk> chunk = decode_chunk(r.samples, &why);
        if (!chunk) throw StoreError(describe(zone) + ": " + describe(r.coord) + ": " + why);
        out.chunks.insert(r.coord, std::move(*chunk));
        out.modified.insert(r.coord);
      }
    };
    const auto compare = [&](const ZoneCheckpoint& c) {
      std::set<world::ChunkCoord> in_checkpoint;
      for (const ChunkRecord& r : c.chunks) {
        in_checkpoint.insert(r.coord);
        const std::optional<world::Chunk> chunk = decode_chunk(r.samples);
        if (!out.chunks.find(r.coord)) out.chunks.insert(r.coord, generator.generate(r.coord));
        ++out.checked;
        if (!chunk || !(*chunk == *out.chunks.find(r.coord))) {
          err << describe(zone) << ": " << describe(r.coord) << " in its checkpoint through record "
              << c.seq << " differs from the log replayed\n";
          ++out.mismatches;
        }
      }
      for (const world::ChunkCoord& m : out.modified) {
        if (world::zone_of(m, size) == zone && !in_checkpoint.count(m)) {
          err << describe(zone) << ": " << describe(m) << " was changed by its log through record "
              << c.seq << " and is missing from its checkpoint\n";
          ++out.mismatches;
        }
      }
    };
    uint64_t at = 0;
    if (!from_seed) {
      install(*cp);
      at = cp->seq;
      ++out.seeded;
    }
    bool compared = !verify || !cp || !from_seed;
    for (;;) {
      const std::vector<ZoneRecord> page = db.read_log(zone, at, kLogPage);
      for (const ZoneRecord& r : page) {
        if (r.seq != at + 1)
          throw StoreError(describe(zone) + ": its log jumps from record " + std::to_string(at) +
                           " to " + std::to_string(r.seq));
        if (!compared && r.seq > cp->seq) {
          compare(*cp);
          compared = true;
        }
        std::string why;
        const std::optional<LoggedEdit> e = decode_zone_edit(r, &why);
        if (!e) throw StoreError(describe(zone) + " record " + std::to_string(r.seq) + ": " + why);
        if (const auto refusal = world::validate(e->edit, limits))
          throw StoreError(describe(zone) + " record " + std::to_string(r.seq) +
                           " is not a valid edit: " + refusal->message);
        for (const world::ChunkCoord& c :
             world::replay_edit(out.chunks, generator, e->edit, e->keep, size))
          out.modified.insert(c);
        at = r.seq;
        ++out.records;
      }
      if (page.size() < kLogPage) break;
    }
    if (!compared) compare(*cp);
    if (at != row->last_seq)
      throw StoreError(describe(zone) + ": its log ends at record " + std::to_string(at) +
                       ", its row says " + std::to_string(row->last_seq));
  }
  return out;
}

void settle_zone_world(ZoneLeases& db, const WorldSettings& settings) {
  const WorldSettings theirs = db.settle_world(settings);
  if (!(theirs == settings))
    throw StoreError("the database holds world " + theirs.name + " (seed " +
                     std::to_string(theirs.seed) + ", zones of " +
                     std::to_string(theirs.zone_chunks) + " chunks), not " + settings.name);
}

void expect_no_records(ZoneLeases& db, const WorldSettings& settings) {
  for (const world::ZoneId zone : db.zones()) {
    if (const std::optional<ZoneRow> row = db.read(zone); row && row->last_seq > 0)
      throw StoreError("the cluster world " + settings.name + " has records already (" +
                       describe(zone) + "): migrate into an empty one");
  }
}

size_t seed_zone_world(ZoneLeases& db, const WorldSettings& settings,
                       const std::map<world::ChunkCoord, const world::Chunk*>& chunks) {
  settle_zone_world(db, settings);
  expect_no_records(db, settings);

  std::map<world::ZoneId, std::vector<ChunkRecord>> by_zone;
  ChunkEncoder encoder;
  for (const auto& [coord, chunk] : chunks)
    by_zone[world::zone_of(coord, settings.zone_chunks)].push_back(
        {coord, 1, encoder.encode(*chunk)});
  // Every zone taken first, then all seeded in one transaction: a migration lands whole or
  // not at all (and can be run again).
  std::vector<ZoneSeed> seeds;
  const auto release_all = [&] {
    for (const ZoneSeed& s : seeds) db.release(s.zone, s.epoch);
  };
  try {
    for (const auto& [zone, records] : by_zone) {
      const std::optional<uint64_t> epoch = db.acquire(zone);
      if (!epoch) throw StoreError(describe(zone) + " is held by a running node: stop the cluster");
      seeds.push_back({zone, *epoch, records});
    }
    db.seed_zones(seeds);
  } catch (...) {
    try {
      release_all();
    } catch (const StoreError&) {
      // The leases run out by themselves.
    }
    throw;
  }
  release_all();
  return by_zone.size();
}

}  // namespace vox::store
