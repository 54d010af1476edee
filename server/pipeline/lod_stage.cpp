#include "server/pipeline/lod_stage.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <stdexcept>

#include "proto/mesh_codec.hpp"
#include "proto/zstd_codec.hpp"
#include "server/mesh/lod_block.hpp"
#include "server/mesh/lod_mesher.hpp"
#include "server/pipeline/lod_pass_quota.hpp"
#include "server/pipeline/stored_chunk_reader.hpp"
#include "server/pipeline/world_state.hpp"
#include "server/store/world_store.hpp"
#include "server/world/overlay_sampler.hpp"
#include "server/world/parallel.hpp"

namespace vox::pipeline {

using world::ChunkCoord;
using world::LodChunk;

struct LodWorker {
  mesh::LodBlock block;
  mesh::LodScratch lod;
  mesh::ChunkMesh mesh;
  proto::CodecScratch codec;
  proto::ZstdCodec zstd;
  uint64_t vertex_passes = 0;  // mesh_lod_vertices calls on `lod`: the codec's key of the last
};

namespace {

// Keys an owner gets per round-robin turn.
constexpr size_t kOwnerTurn = 4;
// Every this many take_missing calls, owners past their first view go first.
constexpr uint64_t kSettledTurn = 4;
// Evicted modified chunks one pass reads back from the store at most, and how long after a
// failed read the stage waits before trying again.
constexpr size_t kStoreReadsPerPass = 32;

// The level-0 chunks whose samples a mesh of `c` reads: its padded block and seams span
// voxels [lo - 2^k, lo + 33 * 2^k].
std::pair<ChunkCoord, ChunkCoord> footprint(const LodChunk& c) {
  const auto lo = c.lo();
  const int64_t step = int64_t{1} << c.level;
  ChunkCoord a, b;
  for (int i = 0; i < 3; ++i) {
    (&a.x)[i] = static_cast<int32_t>(
        world::floor_div(static_cast<int32_t>(lo[i] - step), world::kChunkSize));
    (&b.x)[i] = static_cast<int32_t>(
        world::floor_div(static_cast<int32_t>(lo[i] + 33 * step), world::kChunkSize));
  }
  return {a, b};
}

bool within(ChunkCoord c, ChunkCoord lo, ChunkCoord hi) {
  return c.x >= lo.x && c.x <= hi.x && c.y >= lo.y && c.y <= hi.y && c.z >= lo.z && c.z <= hi.z;
}

}  // namespace

LodStage::LodStage(const world::TerrainGenerator& generator, WorldState& state,
                   LodStageConfig config, StoredChunkReader* reader)
    : generator_(generator),
      state_(state),
      config_(config),
      remesh_(config.levels, config.remesh_interval, config.max_pending_remesh),
      workers_([] { return std::make_unique<LodWorker>(); }),
      grids_(config.grid_cache_bytes),
      reader_(reader) {}

Clock::time_point LodStage::store_retry_at() const {
  return reader_ && reader_->failing() ? reader_->retry_at() : Clock::time_point{};
}

void LodStage::learn_modified() {
  modified_.insert(state_.stored.begin(), state_.stored.end());
  for (const auto& [c, info] : state_.info)
    if (info.modified) modified_.insert(c);
}

LodStage::~LodStage() = default;

void LodStage::want(LoadOwner owner, const LodKey& k) {
  std::vector<LoadOwner>& owners = wanters_[k];
  if (owners.empty()) {
    variants_[k.chunk].push_back(k.seams);
    missing_ = true;
  }
  owners.push_back(owner);
}

void LodStage::unwant(LoadOwner owner, const LodKey& k) {
  auto it = wanters_.find(k);
  if (it == wanters_.end()) return;
  std::vector<LoadOwner>& owners = it->second;
  if (const auto o = std::find(owners.begin(), owners.end(), owner); o != owners.end()) {
    *o = owners.back();
    owners.pop_back();
  }
  if (!owners.empty()) return;
  wanters_.erase(it);
  meshes_.erase(k);
  auto v = variants_.find(k.chunk);
  std::erase(v->second, k.seams);
  if (v->second.empty()) {
    variants_.erase(v);
    remesh_.forget(k.chunk);
  }
}

std::vector<std::pair<LoadOwner, std::shared_ptr<const std::vector<LodKey>>>> LodStage::route(
    const std::vector<LodKey>& published) const {
  std::unordered_map<LoadOwner, std::vector<LodKey>> by_owner;
  for (const LodKey& k : published) {
    const auto it = wanters_.find(k);
    if (it == wanters_.end()) continue;
    for (const LoadOwner o : it->second) by_owner[o].push_back(k);
  }
  std::vector<std::pair<LoadOwner, std::shared_ptr<const std::vector<LodKey>>>> out;
  out.reserve(by_owner.size());
  for (auto& [owner, keys] : by_owner)
    out.emplace_back(owner, std::make_shared<const std::vector<LodKey>>(std::move(keys)));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

std::vector<LodKey> LodStage::set_wants(LoadOwner owner, std::vector<LodKey> keys) {
  std::erase_if(keys, [](const LodKey& k) { return k.chunk.level < 1; });
  for (LodKey& k : keys) k.seams = world::normalized(k.seams);
  auto it = owners_.find(owner);
  // Keys new to this owner that are published already: its session may have looked for
  // them before they were, and routing (route()) did not know it wanted them then.
  std::vector<LodKey> late;
  {
    std::unordered_set<LodKey, LodKeyHash> had;
    if (it != owners_.end()) had.insert(it->second.keys.begin(), it->second.keys.end());
    for (const LodKey& k : keys)
      if (!had.contains(k) && meshes_.get(k)) late.push_back(k);
  }
  for (const LodKey& k : keys) want(owner, k);  // before the old ones go: shared keys stay
  if (it != owners_.end()) {
    for (const LodKey& k : it->second.keys) unwant(owner, k);
    if (keys.empty()) {
      owners_.erase(it);
      return late;
    }
    it->second = Owner{std::move(keys), 0, it->second.first_view, it->second.arrived};
  } else if (!keys.empty()) {
    owners_.emplace(owner, Owner{std::move(keys), 0, true, Clock::now()});
    first_views_wait_ = true;
  }
  missing_ = true;
  return late;
}

void LodStage::edited(const world::VoxelBox& box, Clock::time_point now) {
  // Every chunk the box meets (an edit's box spans a few): those it did not change hold
  // the generated samples, and those not resident are dropped when a footprint is made
  // resident.
  world::for_each_chunk_in(
      world::chunk_of_voxel(box.lo[0], box.lo[1], box.lo[2]),
      world::chunk_of_voxel(box.hi[0], box.hi[1], box.hi[2]), [&](ChunkCoord c) {
        if (const auto it = state_.info.find(c); it != state_.info.end() && it->second.modified)
          modified_.insert(c);
      });
  remesh_.mark(box, now, [this](const LodChunk& c) { return variants_.count(c) > 0; });
}

bool LodStage::has_work(Clock::time_point now) const {
  if (now < store_retry_at()) return false;  // the store failed a read: not before then
  if ((missing_ && !owners_.empty()) || !retry_.empty()) return true;
  const auto due = remesh_.next_due();
  return due && *due <= now;
}

std::optional<Clock::time_point> LodStage::next_due() const {
  std::optional<Clock::time_point> due = remesh_.next_due();
  const Clock::time_point retry_at = store_retry_at();
  if ((missing_ && !owners_.empty()) || !retry_.empty())
    due = due ? std::min(*due, retry_at) : retry_at;
  if (due && *due < retry_at) due = retry_at;
  return due;
}

size_t LodStage::take_keys(Owner& o, size_t turn, size_t max, std::vector<LodKey>& out,
                           std::unordered_set<LodKey, LodKeyHash>& taken) const {
  size_t took = 0;
  for (size_t at = o.cursor; at < o.keys.size() && took < turn && out.size() < max; ++at) {
    const LodKey& k = o.keys[at];
    if (meshes_.get(k)) {
      if (at == o.cursor) ++o.cursor;
      continue;
    }
    if (taken.insert(k).second) {
      out.push_back(k);
      ++took;
    }
  }
  if (o.cursor == o.keys.size()) o.first_view = false;
  return took;
}

void LodStage::take_missing(Clock::time_point now, size_t max, std::vector<LodKey>& out) {
  // First views before the rest: a joining player sees nothing until its whole layout has
  // come, while a walking one only misses a few far chunks for a moment. And first come,
  // first served between first views: shared round robin, every joining player would wait
  // for the whole crowd's backlog, while the oldest first gets most of them done early
  // (and their chunks are most of what the later ones want).
  std::vector<LoadOwner> first, settled;
  for (auto& [id, o] : owners_) {
    if (o.first_view && now - o.arrived >= kFirstViewPriority) o.first_view = false;
    (o.first_view ? first : settled).push_back(id);
  }
  std::sort(first.begin(), first.end());
  std::sort(settled.begin(), settled.end());
  std::unordered_set<LodKey, LodKeyHash> taken(out.begin(), out.end());
  const auto serve_first = [&] {
    for (const LoadOwner id : first) {
      if (out.size() >= max) return;
      take_keys(owners_.at(id), SIZE_MAX, max, out, taken);
    }
  };
  const auto serve_settled = [&] {
    bool any = true;
    while (out.size() < max && any) {
      any = false;
      for (size_t i = 0; i < settled.size() && out.size() < max; ++i) {
        Owner& o = owners_.at(settled[(next_owner_ + i) % settled.size()]);
        any |= take_keys(o, kOwnerTurn, max, out, taken) > 0;
      }
    }
    if (!settled.empty()) next_owner_ = (next_owner_ + 1) % settled.size();
  };
  if (++missing_calls_ % kSettledTurn == 0) {
    serve_settled();
    serve_first();
  } else {
    serve_first();
    serve_settled();
  }
  if (out.size() < max) missing_ = false;  // every owner's keys are published or taken
  first_views_wait_ = std::any_of(first.begin(), first.end(),
                                  [this](LoadOwner id) { return owners_.at(id).first_view; });
}

LodStage::Resident LodStage::make_resident(const LodChunk& c, Clock::time_point now,
                                           size_t& reads_left) {
  const auto [lo, hi] = footprint(c);
  std::vector<ChunkCoord> missing;
  const int64_t box =
      (int64_t{hi.x} - lo.x + 1) * (int64_t{hi.y} - lo.y + 1) * (int64_t{hi.z} - lo.z + 1);
  // A resident one is marked used: read back over several passes, the first ones must not
  // be evicted (as idle) before the last ones are in, or a slow machine never gets there.
  const auto look = [&](ChunkCoord m) {
    if (const auto it = state_.info.find(m); it != state_.info.end())
      it->second.last_used = now;
    else
      missing.push_back(m);
  };
  if (box <= static_cast<int64_t>(modified_.size())) {
    world::for_each_chunk_in(lo, hi, [&](ChunkCoord m) {
      if (modified_.contains(m)) look(m);
    });
  } else {
    for (const ChunkCoord m : modified_)
      if (within(m, lo, hi)) look(m);
  }
  std::erase_if(missing, [&](ChunkCoord m) {
    if (state_.stored.count(m)) return false;
    modified_.erase(m);  // generated terrain: nothing to lay over it
    return true;
  });
  // At most reads_left this pass: later passes read the rest (a pass never stalls on the
  // store, and a footprint needing more than one pass's reads still gets there).
  const bool all = missing.size() <= reads_left;
  if (!all) missing.resize(reads_left);
  for (const ChunkCoord m : missing) {
    // Stored chunks only (the others were dropped above), so there is a store and a reader.
    if (!reader_->try_load(state_, m, now)) return Resident::kFailed;
    --reads_left;
  }
  return all ? Resident::kReady : Resident::kLater;
}

LodStage::RunResult LodStage::run(Clock::time_point now, size_t max_chunks,
                                  const std::vector<ChunkCoord>& unsettled) {
  if (now < store_retry_at()) return {};
  // Chunks the re-mesh queue dropped: their meshes are stale, mesh them afresh.
  for (const LodChunk& c : remesh_.take_dropped()) {
    if (const auto v = variants_.find(c); v != variants_.end())
      for (const world::LodSeams s : v->second) meshes_.erase({c, s});
    missing_ = true;
  }
  std::vector<LodChunk> chunks;
  chunks.swap(retry_);  // put off by the store first
  std::sort(chunks.begin(), chunks.end());
  chunks.erase(std::unique(chunks.begin(), chunks.end()), chunks.end());
  // Re-meshes and missing meshes share the pass (lod_pass_quota.hpp).
  const bool missing = missing_ && !owners_.empty();
  const bool remesh_turn = lod_remesh_turn(missing && first_views_wait_, ++passes_);
  if (const size_t due = lod_remesh_quota(max_chunks, chunks.size(), missing);
      due > 0 && remesh_turn) {
    for (const LodChunk& c : remesh_.take_due(now, due)) chunks.push_back(c);
  }
  std::vector<LodKey> keys;
  for (const LodChunk& c : chunks) {
    const auto v = variants_.find(c);
    if (v == variants_.end()) continue;
    for (const world::LodSeams s : v->second) keys.push_back({c, s});
  }
  const size_t remesh_keys = keys.size();  // re-meshes (and meshes the store put off)
  if (missing)
    take_missing(now, keys.size() + lod_missing_quota(max_chunks, chunks.size(), true), keys);
  size_t reads_left = kStoreReadsPerPass;
  std::vector<LodKey> ready;
  std::array<uint64_t, kCountedLevels> remeshed{};
  size_t deferred = 0;
  for (size_t i = 0; i < keys.size(); ++i) {
    const LodKey& k = keys[i];
    if (!unsettled.empty()) {
      const std::pair<ChunkCoord, ChunkCoord> box = footprint(k.chunk);
      if (std::any_of(unsettled.begin(), unsettled.end(),
                      [&](ChunkCoord c) { return within(c, box.first, box.second); })) {
        // A re-mesh (all its variants) comes back first next pass; a missing mesh is
        // taken again, the owner's cursor not having passed it.
        if (i < remesh_keys) retry_.push_back(k.chunk);
        missing_ = missing_ || i >= remesh_keys;
        ++deferred;
        continue;
      }
    }
    const Resident r = make_resident(k.chunk, now, reads_left);
    if (r == Resident::kReady) {
      ready.push_back(k);
      if (i < remesh_keys) ++remeshed[std::min(k.chunk.level, kCountedLevels - 1)];
      continue;
    }
    retry_.push_back(k.chunk);  // whether a re-mesh or a missing mesh: all its variants
  }
  if (ready.empty()) return {{}, deferred};
  std::vector<LodKey> published = mesh_and_publish(std::move(ready));
  // Counted after meshed_ (mesh_and_publish): a reader never sees more re-meshes than meshes.
  for (int level = 0; level < kCountedLevels; ++level)
    if (remeshed[level] > 0) remeshed_[level].fetch_add(remeshed[level], std::memory_order_relaxed);
  return {std::move(published), deferred};
}

std::vector<LodKey> LodStage::mesh_and_publish(std::vector<LodKey> keys) {
  const world::OverlaySampler sampler(
      generator_, modified_,
      [this](ChunkCoord c) -> const world::Chunk& {
        const world::Chunk* chunk = state_.chunks.find(c);
        if (!chunk) throw std::logic_error("lod: a modified chunk is not resident");
        return *chunk;
      },
      &grids_);
  // One task per chunk: its samples are gathered once, for every seams variant wanted (a
  // point holds the same sample whichever seams read it), its regular vertices made once,
  // and each variant meshed from them.
  std::sort(keys.begin(), keys.end(),
            [](const LodKey& a, const LodKey& b) { return a.chunk < b.chunk; });
  std::vector<size_t> starts;
  for (size_t i = 0; i < keys.size(); ++i)
    if (i == 0 || !(keys[i].chunk == keys[i - 1].chunk)) starts.push_back(i);
  starts.push_back(keys.size());
  std::vector<std::shared_ptr<MeshVersion>> fresh(keys.size());
  std::vector<uint8_t> made(keys.size(), 0);  // sampled and meshed (fresh: and changed)
  std::atomic<size_t> failed{0};
  parallel_for_index(state_.arena, starts.size() - 1, [&](size_t g) {
    LodWorker& w = *workers_.local();
    const size_t begin = starts[g], end = starts[g + 1];
    world::LodSeams all;
    for (size_t i = begin; i < end; ++i) {
      all.faces |= keys[i].seams.faces;
      all.edges |= keys[i].seams.edges;
    }
    try {
      mesh::gather_lod_block(sampler, keys[begin].chunk, all, w.block);
    } catch (const std::exception&) {  // a coordinate out of range, a lookup failing
      failed.fetch_add(end - begin, std::memory_order_relaxed);
      return;
    }
    mesh::mesh_lod_vertices(w.block, w.lod);  // shared by the variants
    ++w.vertex_passes;
    for (size_t i = begin; i < end; ++i) {
      fresh[i] = mesh_variant(keys[i], w);
      made[i] = 1;
    }
  });
  if (failed.load() > 0)
    spdlog::error("lod: {} coarse chunks could not be sampled; they stay unpublished",
                  failed.load());
  std::vector<LodKey> published;
  for (size_t i = 0; i < keys.size(); ++i) {
    const int level = std::min(keys[i].chunk.level, kCountedLevels - 1);
    meshed_[level].fetch_add(made[i], std::memory_order_relaxed);
    if (!fresh[i]) continue;
    published_[level].fetch_add(1, std::memory_order_relaxed);
    fresh[i]->version = next_version_++;
    meshes_.publish(keys[i], std::move(fresh[i]));
    published.push_back(keys[i]);
  }
  return published;
}

std::shared_ptr<MeshVersion> LodStage::mesh_variant(const LodKey& k, LodWorker& w) const {
  w.block.seams = world::normalized(k.seams);
  mesh::mesh_lod_variant(w.block, w.lod, w.mesh);
  auto v = std::make_shared<MeshVersion>();
  v->coord = k.chunk.c;
  proto::encode_lod_mesh(w.mesh, w.lod, w.codec, v->encoding, w.vertex_passes);
  const MeshVersionPtr old = meshes_.get(k);
  if (old && old->encoding == v->encoding) return nullptr;        // unchanged
  v->triangles = static_cast<uint32_t>(w.mesh.triangle_count());  // the mesh is not kept
  if (!old) w.zstd.compress(v->encoding, {}, v->full_frame);      // a re-mesh's: when asked
  return v;
}

}  // namespace vox::pipeline
