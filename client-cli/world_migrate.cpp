// voxel-cli world migrate --from WORLD --to WORLD: a single node's world into a cluster
// world's database, or a cluster world out into a single node's world (docs/CLUSTER.md,
// "Moving in"), and voxel-cli world verify|info of a cluster world. Offline: the source is
// only read; the target must be empty and no node may run on it.
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <ostream>
#include <stdexcept>

#include "client-cli/cli_options.hpp"
#include "client-cli/commands.hpp"
#include "server/store/chunk_codec.hpp"
#include "server/store/postgres_store.hpp"
#include "server/store/world_history.hpp"
#include "server/store/world_store.hpp"
#include "server/store/zone_world.hpp"
#include "server/world/edit_replay.hpp"

namespace vox::cli {
namespace {

constexpr std::chrono::milliseconds kToolLease{30000};

// "X,Z": a zone's coordinates (whole numbers, in zones).
world::ZoneId parse_zone(const std::string& text) {
  const std::array<float, 2> f = parse_vec2(text, "--zone");
  for (const float v : f) {
    if (v != std::floor(v) || std::fabs(v) > 1e7f)
      throw std::invalid_argument("world migrate: --zone must be whole zone coordinates X,Z");
  }
  return {static_cast<int32_t>(f[0]), static_cast<int32_t>(f[1])};
}

// A single node's world as its store leaves it: its checkpointed chunks, then the log
// after the checkpoint replayed. `modified`: every chunk either holds.
void load_single_world(store::WorldStore& s, world::ChunkMap& map,
                       std::set<world::ChunkCoord>& modified) {
  const store::WorldInfo info = s.info();
  const world::TerrainGenerator generator(info.seed);
  std::vector<world::ChunkCoord> stored;
  s.for_each_chunk([&](world::ChunkCoord c, uint64_t) { stored.push_back(c); });
  for (const world::ChunkCoord& c : stored) {
    map.insert(c, store::read_checkpointed_chunk(s, c));
    modified.insert(c);
  }
  world::EditLimits limits;
  limits.max_radius = limits.max_strength = 1e9f;  // the server's limits may have been wider
  auto rollbacks = store::replay_rollbacks_after(s, generator, info.checkpoint_seq);
  s.for_each_edit(info.checkpoint_seq, [&](const store::LoggedEdit& e) {
    if (e.undoes) {
      for (auto& [c, chunk] : rollbacks.at(e.seq)) {
        map.insert(c, std::move(chunk));
        modified.insert(c);
      }
      return true;
    }
    if (auto refusal = world::validate(e.edit, limits))
      throw std::runtime_error("logged edit " + std::to_string(e.seq) +
                               " is not valid: " + refusal->message);
    for (const world::ChunkCoord& c : world::replay_edit(map, generator, e.edit, e.keep))
      modified.insert(c);
    return true;
  });
}

int migrate_in(const std::string& from, const std::string& to, const std::string& name,
               int zone_chunks, std::ostream& out) {
  auto source = store::open_world_store(from, {.read_only = true});
  const store::RegionTable regions = source->read_regions();
  world::ChunkMap map;
  std::set<world::ChunkCoord> modified;
  load_single_world(*source, map, modified);
  std::map<world::ChunkCoord, const world::Chunk*> chunks;
  for (const world::ChunkCoord& c : modified) chunks[c] = map.find(c);
  store::ZoneLeases db(to, "voxel-cli-migrate", kToolLease);
  // The regions before the zones: a target with records or other regions is refused
  // before they are written (one that has these regions already, from a migration cut
  // short, keeps them).
  const store::WorldSettings settings{
      .name = name, .seed = source->info().seed, .zone_chunks = zone_chunks};
  store::settle_zone_world(db, settings);
  store::expect_no_records(db, settings);
  const std::vector<world::Region> there = db.read_regions().table.regions;
  const auto ids = [](const std::vector<world::Region>& rs) {
    std::vector<uint64_t> out;
    for (const world::Region& r : rs) out.push_back(r.id);
    return out;
  };
  if (!there.empty() && ids(there) != ids(regions.regions))
    throw std::runtime_error("the cluster world has other protected regions already");
  if (there.empty() && (!regions.regions.empty() || regions.next_id > 1)) db.seed_regions(regions);
  const size_t zones = store::seed_zone_world(db, settings, chunks);
  out << "migrate: " << source->name() << " into cluster world " << name << " ("
      << store::redact_uri(to) << "): " << chunks.size() << " chunks in " << zones << " zones of "
      << zone_chunks << " chunks, " << regions.regions.size() << " protected regions\n";
  return 0;
}

// `only`: one zone's chunks alone (the rest of the target is the generated terrain).
int migrate_out(const std::string& from, const std::string& to, std::optional<world::ZoneId> only,
                std::ostream& out, std::ostream& err) {
  store::ZoneLeases db(from, "voxel-cli-migrate", kToolLease);
  if (only) {
    const std::vector<world::ZoneId> zones = db.zones();
    if (std::find(zones.begin(), zones.end(), *only) == zones.end())
      throw std::runtime_error("the cluster world has no zone (" + std::to_string(only->x) + ", " +
                               std::to_string(only->z) + ")");
  }
  const store::ZoneWorld zw = store::read_zone_world(db, false, err);
  auto target =
      store::open_world_store(to, {.seed = zw.settings.seed, .new_world_seed = zw.settings.seed});
  const store::WorldInfo info = target->info();
  if (info.last_seq > 0 || info.modified_chunks > 0)
    throw std::runtime_error(target->name() + " is not empty: migrate into a new world");
  std::vector<store::ChunkRecord> records;
  store::ChunkEncoder encoder;
  for (const world::ChunkCoord& c : zw.modified) {
    if (!only || world::zone_of(c, zw.settings.zone_chunks) == *only)
      records.push_back({c, 1, encoder.encode(*zw.chunks.find(c))});
  }
  target->write_checkpoint(records, 1, 0);
  target->reset_base();  // its history starts with the chunks it was given, not the seed
  // The protected regions: all of them (a region may reach past the zone taken alone).
  const store::ZoneRegions regions = db.read_regions();
  const store::RegionWrite write{.whole = true,
                                 .upsert = regions.table.regions,
                                 .remove = {},
                                 .next_id = regions.table.next_id};
  target->append_edits({}, {}, &write);
  out << "migrate: cluster world " << zw.settings.name;
  if (only) out << ", zone (" << only->x << ", " << only->z << ") alone";
  out << " (" << zw.zones << " zones, " << zw.records << " records replayed) into "
      << target->name() << ": " << records.size() << " chunks, " << regions.table.regions.size()
      << " protected regions\n";
  return 0;
}

}  // namespace

int world_migrate(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  po::options_description opts("voxel-cli world migrate options");
  opts.add_options()("help,h", "show this help")(
      "from", po::value<std::string>()->required(),
      "the world to read: a world directory, a postgresql:// URI (a single node's world or a "
      "cluster's database)")("to", po::value<std::string>()->required(),
                             "the empty world to write: a cluster's postgresql:// database "
                             "(from a single node's world), or a world directory")(
      "name", po::value<std::string>(), "into a cluster: the world's name (its nodes' `world`)")(
      "zone-chunks", po::value<int>()->default_value(16),
      "into a cluster: the zones' size in chunks (its nodes' `zone_chunks`)")(
      "zone", po::value<std::string>(),
      "out of a cluster: only the zone X,Z (its chunks; the rest is the generated terrain)");
  po::variables_map vm;
  const int rc = parse_options(
      args, opts, nullptr,
      "usage: voxel-cli world migrate --from WORLD --to postgresql://... --name NAME\n"
      "       voxel-cli world migrate --from postgresql://... --to WORLD [--zone X,Z]",
      vm, out, err);
  if (rc >= 0) return rc;
  return guarded(err, [&] {
    const std::string from = vm["from"].as<std::string>(), to = vm["to"].as<std::string>();
    std::optional<world::ZoneId> only;  // a usage error before any connection
    if (vm.count("zone")) only = parse_zone(vm["zone"].as<std::string>());
    if (store::is_postgres_uri(from) && store::is_cluster_world(from))
      return migrate_out(from, to, only, out, err);
    if (only) throw std::invalid_argument("world migrate: --zone takes one zone out of a cluster");
    if (!store::is_postgres_uri(to))
      throw std::invalid_argument("world migrate: --to must be a cluster's postgresql:// database");
    if (!vm.count("name"))
      throw std::invalid_argument("world migrate: --name is needed to migrate into a cluster");
    const int zone_chunks = vm["zone-chunks"].as<int>();
    if (zone_chunks < 1 || zone_chunks > 1024)
      throw std::invalid_argument("world migrate: --zone-chunks must be 1..1024");
    return migrate_in(from, to, vm["name"].as<std::string>(), zone_chunks, out);
  });
}

int cluster_world_command(const std::string& action, const std::string& uri, std::ostream& out,
                          std::ostream& err) {
  store::ZoneLeases db(uri, "voxel-cli", kToolLease);
  const store::ZoneWorld zw = store::read_zone_world(db, action == "verify", err);
  out << "cluster world " << zw.settings.name << " (seed " << zw.settings.seed << ", zones of "
      << zw.settings.zone_chunks << " chunks): " << zw.zones << " zones, " << zw.records
      << " records replayed, " << zw.modified.size() << " modified chunks, "
      << db.read_regions().table.regions.size() << " protected regions";
  if (zw.seeded > 0) out << ", " << zw.seeded << " zones from their migrated checkpoints";
  if (action != "verify") {
    out << "\n";
    return 0;
  }
  out << "; verify: " << zw.checked << " checkpointed chunks checked: "
      << (zw.mismatches == 0 ? "all match" : std::to_string(zw.mismatches) + " differ") << "\n";
  return zw.mismatches == 0 ? 0 : 1;
}

}  // namespace vox::cli
