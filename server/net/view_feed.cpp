// The view feed: a view and its level-of-detail layout as the player moves (their unloads
// and the pipeline's wants), and the messages that send them.
#include "server/net/view_feed.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "server/net/wire_convert.hpp"

namespace vox::net {

using world::ChunkCoord;
using world::LodChunk;
using Clock = std::chrono::steady_clock;

namespace {

// Into the payload's capacity: set_payload(p, n) builds a temporary string (protobuf 3.21),
// an allocation per mesh.
void set_payload(wire::ChunkMesh& m, std::span<const uint8_t> bytes) {
  m.mutable_payload()->assign(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

}  // namespace

ViewFeed::ViewFeed(const pipeline::MeshStore& meshes, const pipeline::LodMeshStore& lod_meshes,
                   Wants wants, ServerCounters& counters)
    : meshes_(meshes), lod_meshes_(lod_meshes), wants_(std::move(wants)), counters_(counters) {}

std::vector<wire::Envelope> ViewFeed::apply_view(const View& v) {
  std::vector<wire::Envelope> unloads;
  view_id_ = v.view_id;
  level0_done_.reset();
  lod_done_.reset();
  SendScheduler::Keep keep;  // a LOD view's level-0 chunks
  const int r = v.lod_level > 0 ? apply_lod_view(v, keep, unloads) : v.radius;
  if (v.lod_level == 0) drop_lod_view(unloads);
  {
    std::lock_guard lock(view_mutex_);
    view_center_ = v.center;
    view_radius_ = r;
  }
  const std::vector<ChunkCoord> left = scheduler_.set_view(v.center, r, keep);
  if (!left.empty()) {
    wire::Envelope& unload = unloads.emplace_back();
    for (const ChunkCoord& c : left) *unload.mutable_chunk_unload()->add_coords() = to_wire(c);
  }
  // The pipeline loads what is missing (this view replaces the previous one); newly
  // published meshes arrive through chunks_published().
  wants_.set_view(v.center, r, keep);
  return unloads;
}

// The layout: levels 0 .. lod_level, the 3x3x3 top-level chunks around the eye; level-1
// chunks split within about `radius` chunks (so level 0 reaches that far), coarser ones
// within lod_distance of their side. Returns the radius of the ball holding every level-0
// chunk of the layout, and in `keep` which of the ball's chunks those are.
int ViewFeed::apply_lod_view(const View& v, SendScheduler::Keep& keep,
                             std::vector<wire::Envelope>& out) {
  const world::LodSettings settings{.levels = v.lod_level + 1,
                                    .top_radius = 1,
                                    .split_distance = v.lod_distance,
                                    .near_split_distance = std::max(0.5, v.radius / 2.0)};
  const bool same = lod_view_ && lod_settings_.levels == settings.levels &&
                    lod_settings_.split_distance == settings.split_distance &&
                    lod_settings_.near_split_distance == settings.near_split_distance;
  if (!same) {
    drop_lod_view(out);
    lod_view_.emplace(settings);
    lod_settings_ = settings;
  }
  const world::LodViewChange change = lod_view_->update(v.eye);  // eye checked: finite, bounded
  add_lod_unloads(lod_queue_.apply(change, v.eye), out);
  if (!change.empty() || !lod_level0_) {
    // The layout changed: its level-0 chunks and the pipeline's wants with it (a walking
    // player's SetViews mostly leave the layout as it was).
    auto level0 = std::make_shared<Level0>();
    for (const LodChunk& c : lod_view_->layout().chunks())
      if (c.level == 0) level0->insert(c.c);
    lod_level0_ = std::move(level0);
    wants_.set_lod_view(lod_queue_.wants());
  }
  int64_t r2 = 0;
  for (const ChunkCoord c : *lod_level0_) {
    const int64_t dx = c.x - v.center.x, dy = c.y - v.center.y, dz = c.z - v.center.z;
    r2 = std::max(r2, dx * dx + dy * dy + dz * dz);
  }
  keep = [level0 = lod_level0_](ChunkCoord c) { return level0->count(c) > 0; };
  lod_active_.store(true, std::memory_order_relaxed);
  return static_cast<int>(std::ceil(std::sqrt(static_cast<double>(r2))));
}

// Unloads every LOD chunk the client holds.
void ViewFeed::drop_lod_view(std::vector<wire::Envelope>& out) {
  if (!lod_view_) return;
  std::vector<LodChunk> held;
  for (const auto& [c, seams] : lod_view_->held()) held.push_back(c);
  std::sort(held.begin(), held.end());  // the same ChunkUnloads whatever the map's order
  world::LodViewChange gone;
  gone.unload = held;
  add_lod_unloads(lod_queue_.apply(gone, {}), out);
  lod_queue_.clear();
  lod_view_.reset();
  lod_level0_.reset();
  lod_active_.store(false, std::memory_order_relaxed);
  wants_.set_lod_view({});
}

// One ChunkUnload per level, finer first.
void ViewFeed::add_lod_unloads(const std::vector<LodChunk>& chunks,
                               std::vector<wire::Envelope>& out) {
  std::map<int, wire::Envelope> by_level;
  for (const LodChunk& c : chunks) {
    auto* u = by_level[c.level].mutable_chunk_unload();
    u->set_level(static_cast<uint32_t>(c.level));
    *u->add_coords() = to_wire(c.c);
  }
  for (auto& [level, message] : by_level) out.push_back(std::move(message));
}

bool ViewFeed::may_see(const std::vector<ChunkCoord>& chunks) const {
  ChunkCoord center;
  int64_t r;
  {
    std::lock_guard lock(view_mutex_);
    center = view_center_;
    r = view_radius_;
  }
  if (r < 0) return false;
  for (const ChunkCoord& c : chunks) {
    const int64_t dx = c.x - center.x, dy = c.y - center.y, dz = c.z - center.z;
    if (dx * dx + dy * dy + dz * dz <= r * r) return true;
  }
  return false;
}

bool ViewFeed::chunks_published(const std::vector<ChunkCoord>& chunks) {
  if (!scheduler_.has_view()) return false;
  for (const ChunkCoord& c : chunks) scheduler_.mark_stale(c);
  return true;
}

bool ViewFeed::lod_published(const std::vector<pipeline::LodKey>& keys) {
  if (!lod_view_) return false;
  for (const pipeline::LodKey& k : keys) lod_queue_.mark_stale(k);
  return true;
}

bool ViewFeed::resync(int level, ChunkCoord c) {
  return level == 0 ? scheduler_.resync(c) : lod_queue_.resync(LodChunk{level, c});
}

bool ViewFeed::release_deferred() {
  if (scheduler_.deferred_count() == 0) return false;
  scheduler_.release_deferred();
  return true;
}

void ViewFeed::begin_write() {
  write_edits_.clear();
  level0_exhausted_ = false;
}

const wire::Envelope* ViewFeed::next_mesh(uint64_t first_unsendable) {
  // Coarser levels after every level-0 mesh due (PROTOCOL 4.10), nearest first.
  if (!level0_exhausted_ && next_level0_mesh(first_unsendable)) return &mesh_message_;
  level0_exhausted_ = true;
  return next_lod_mesh() ? &mesh_message_ : nullptr;
}

// The newest version of the nearest stale chunk the client does not hold yet (a delta
// when it holds an older one) into mesh_message_; false when nothing is left to send.
bool ViewFeed::next_level0_mesh(uint64_t first_unsendable) {
  const auto send =
      scheduler_.next([this](ChunkCoord c) { return meshes_.get(c); }, first_unsendable);
  if (!send) return false;
  auto* m = mesh_message_.mutable_chunk_mesh();
  m->set_level(0);  // the message is reused for coarser meshes
  *m->mutable_coord() = to_wire(send->coord);
  m->set_version(send->version->version);
  const bool delta =
      fill_payload(*m, *send->version, send->base.get(), send->base ? send->base->version : 0);
  if (delta && send->version->edited_at != Clock::time_point{})
    write_edits_.push_back(send->version->edited_at);
  return true;
}

bool ViewFeed::next_lod_mesh() {
  if (!lod_view_) return false;
  const auto send =
      lod_queue_.next([this](const pipeline::LodKey& k) { return lod_meshes_.get(k); });
  if (!send) return false;
  auto* m = mesh_message_.mutable_chunk_mesh();
  *m->mutable_coord() = to_wire(send->chunk.c);
  m->set_level(static_cast<uint32_t>(send->chunk.level));
  m->set_version(send->wire_version);
  fill_payload(*m, *send->version, send->base.get(), send->wire_base);
  return true;
}

// `version` as a delta from `base` (the client holds it, as `wire_base` on the wire), or
// in full without one; counted. Returns whether it was a delta.
bool ViewFeed::fill_payload(wire::ChunkMesh& m, const pipeline::MeshVersion& version,
                            const pipeline::MeshVersion* base, uint64_t wire_base) {
  counters_.meshes_sent.fetch_add(1, std::memory_order_relaxed);
  const size_t level = std::min<size_t>(m.level(), ServerCounters::kLevels - 1);
  const size_t delta = base ? 1 : 0;
  if (!base) {
    m.set_base_version(0);
    set_payload(m, version.full());
  } else {
    m.set_base_version(wire_base);
    set_payload(m, *version.delta_from(*base));
    counters_.deltas_sent.fetch_add(1, std::memory_order_relaxed);
  }
  counters_.mesh_bytes[level][delta].fetch_add(m.payload().size(), std::memory_order_relaxed);
  counters_.mesh_messages[level][delta].fetch_add(1, std::memory_order_relaxed);
  return base != nullptr;
}

// Once per applied view, when its every chunk (of every level) has been sent or found
// empty.
bool ViewFeed::take_view_ready(wire::Envelope& out) {
  if (!level0_done_) level0_done_ = scheduler_.take_view_complete();
  if (!level0_done_) return false;
  if (lod_view_ && !lod_done_) lod_done_ = lod_queue_.take_complete();
  if (lod_view_ && !lod_done_) return false;
  auto* r = out.mutable_view_ready();
  r->set_view_id(view_id_);
  *r->mutable_center() = to_wire(view_center_);  // strand: its only writer
  r->set_radius(static_cast<uint32_t>(view_radius_));
  r->set_chunks_sent(level0_done_->sent);
  r->set_chunks_empty(level0_done_->empty);
  if (lod_done_) {
    r->set_lod_chunks_sent(lod_done_->sent);
    r->set_lod_chunks_empty(lod_done_->empty);
  }
  level0_done_.reset();
  lod_done_.reset();
  return true;
}

void ViewFeed::written() {
  if (write_edits_.empty()) return;
  const auto now = Clock::now();
  for (const auto submitted : write_edits_) {
    counters_.edit_to_delta_written.observe(std::chrono::duration<double>(now - submitted).count());
  }
  write_edits_.clear();
}

void ViewFeed::clear() {
  scheduler_.clear();
  lod_queue_.clear();
  lod_view_.reset();
  lod_active_.store(false, std::memory_order_relaxed);
}

// Map node (~64) + an entry in the updates or new-chunk heap (24), in the waiting heap (24)
// and in the deferred list (12), at most, per visible chunk; a layout chunk: in the
// LodView's leaves and held map, the LodSendQueue and the level-0 set.
size_t ViewFeed::memory_bytes() const {
  constexpr size_t kPerVisibleChunk = 128;
  constexpr size_t kPerLodChunk = 384;
  const size_t lod_chunks = lod_view_ ? lod_view_->held().size() : 0;
  return scheduler_.visible_count() * kPerVisibleChunk + lod_chunks * kPerLodChunk;
}

}  // namespace vox::net
