// What a session's client sees (docs/PROTOCOL.md 4.3, 4.10): the view it asked for, what
// it holds of it, and the next message that feeds it. Level-0 chunks go through the
// SendScheduler (updates of held chunks, then new chunks nearest first), a level-of-detail
// view's coarser chunks through the LodSendQueue after them, each the newest version as a
// delta from what the client holds; a ViewReady follows once per view, when its every
// chunk (of every level) has been sent or found empty. The feed knows no socket, strand
// or timer: its session applies the views it checked, asks for the next message to
// append to its write, and sends the unloads it is given. It reaches the pipeline only
// through the stores and the two wants it is given. Strand only, but may_see() and
// has_lod_view(), which any thread may call.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_set>
#include <vector>

#include "server/net/lod_send_queue.hpp"
#include "server/net/send_scheduler.hpp"
#include "server/net/server_counters.hpp"
#include "server/pipeline/lod_mesh_store.hpp"
#include "server/pipeline/mesh_store.hpp"
#include "server/world/lod_view.hpp"
#include "voxel.pb.h"

namespace vox::net {

class ViewFeed {
 public:
  // What the feed asks of the pipeline for its client (the session binds its id): the
  // chunks to load (a ball, filtered by `keep` for a level-of-detail layout), and the
  // coarser meshes its layout wants, nearest first. Called on the feed's thread.
  struct Wants {
    std::function<void(world::ChunkCoord center, int radius, const SendScheduler::Keep& keep)>
        set_view;
    std::function<void(std::vector<pipeline::LodKey> keys)> set_lod_view;
  };
  // Any thread, before the feed is used; the stores and counters outlive it.
  ViewFeed(const pipeline::MeshStore& meshes, const pipeline::LodMeshStore& lod_meshes, Wants wants,
           ServerCounters& counters);

  // A SetView, checked by the session.
  struct View {
    world::ChunkCoord center;
    int radius = 0;
    uint64_t view_id = 0;
    std::array<double, 3> eye{};  // voxels
    int lod_level = 0;            // 0: level 0 only
    double lod_distance = 1.0;
  };
  // Strand only: the view replaces the previous one. Returns the ChunkUnloads of what the
  // client holds and no longer sees, in their order, to send before anything of the view.
  std::vector<wire::Envelope> apply_view(const View& v);
  bool has_view() const { return scheduler_.has_view(); }  // strand only
  // Any thread: false when none of `chunks` can be in the view, so the publish fan-out
  // skips this client. apply_view() updates it before asking the pipeline for the view,
  // so a mesh published meanwhile is either looked up or passes this filter.
  bool may_see(const std::vector<world::ChunkCoord>& chunks) const;
  bool has_lod_view() const { return lod_active_.load(std::memory_order_relaxed); }  // any thread

  // Strand only: new versions were published; false when there is no view to feed.
  bool chunks_published(const std::vector<world::ChunkCoord>& chunks);
  bool lod_published(const std::vector<pipeline::LodKey>& keys);  // strand only
  // Strand only: the client dropped `c` of `level`; its newest version goes in full. False
  // when it is not in the view.
  bool resync(int level, world::ChunkCoord c);
  // Strand only: versions held back for an edit's result may go; false when there were none.
  bool release_deferred();

  // Strand only: a new write begins (what an unfinished one carried is forgotten).
  void begin_write();
  // Strand only: the next mesh (level 0, then coarser levels), recorded as held; no version
  // at or above `first_unsendable` goes (it may show an edit whose result is not sent). The
  // message is reused: valid until the next call. Null when nothing is left.
  const wire::Envelope* next_mesh(uint64_t first_unsendable);
  // Strand only: the view's ViewReady into `out`, once, after its last mesh; else false.
  bool take_view_ready(wire::Envelope& out);
  // Strand only: the write carrying the meshes went out (observes edit -> delta written).
  void written();

  void clear();  // strand only: the session ends; nothing more is fed
  // Strand only: accounted memory of the view map and the level-of-detail layout.
  size_t memory_bytes() const;

 private:
  using Level0 = std::unordered_set<world::ChunkCoord, world::ChunkCoordHash>;
  int apply_lod_view(const View& v, SendScheduler::Keep& keep, std::vector<wire::Envelope>& out);
  void drop_lod_view(std::vector<wire::Envelope>& out);
  static void add_lod_unloads(const std::vector<world::LodChunk>& chunks,
                              std::vector<wire::Envelope>& out);
  bool next_level0_mesh(uint64_t first_unsendable);
  bool next_lod_mesh();
  bool fill_payload(wire::ChunkMesh& m, const pipeline::MeshVersion& version,
                    const pipeline::MeshVersion* base, uint64_t wire_base);

  const pipeline::MeshStore& meshes_;
  const pipeline::LodMeshStore& lod_meshes_;
  const Wants wants_;
  ServerCounters& counters_;

  SendScheduler scheduler_;
  // Level of detail: the client's layout (none: a level-0 view), what it holds of levels
  // >= 1, and the two halves of the view-complete marker.
  std::optional<world::LodView> lod_view_;
  world::LodSettings lod_settings_;
  std::shared_ptr<const Level0> lod_level0_;  // the layout's level 0 (the scheduler's filter)
  LodSendQueue lod_queue_;
  std::atomic<bool> lod_active_{false};
  std::optional<SendScheduler::ViewComplete> level0_done_;
  std::optional<LodSendQueue::Complete> lod_done_;
  uint64_t view_id_ = 0;           // of the view applied last (echoed in its ViewReady)
  mutable std::mutex view_mutex_;  // guards the two below (also read by the fan-out)
  world::ChunkCoord view_center_{};
  int view_radius_ = -1;

  wire::Envelope mesh_message_;    // reused for every mesh: its payload keeps its capacity
  bool level0_exhausted_ = false;  // in this write: the coarser levels' turn
  // When the edits shown by the deltas of the write in flight were submitted; capacity
  // reused.
  std::vector<std::chrono::steady_clock::time_point> write_edits_;
};

}  // namespace vox::net
