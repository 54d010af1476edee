// One connected player. Each session runs on its connection's strand: messages come in
// from the Connection (the transport: TCP frames, connection.hpp), are parsed and
// dispatched to the handlers; edits pass its EditGate (edit_gate.hpp), views its checks
// and rate into its ViewFeed (view_feed.hpp). A write sends control messages first, then
// what the feed gives (meshes, then the view's ViewReady). Other threads only post to the
// strand.
#pragma once

#include <chrono>
#include <deque>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "server/auth/player_token.hpp"
#include "server/net/admission_control.hpp"
#include "server/net/asio.hpp"
#include "server/net/ban_keeper.hpp"
#include "server/net/connection.hpp"
#include "server/net/edit_gate.hpp"
#include "server/net/live_settings.hpp"
#include "server/net/log_hygiene.hpp"
#include "server/net/player_registry.hpp"
#include "server/net/query_gate.hpp"
#include "server/net/result_order.hpp"
#include "server/net/server_config.hpp"
#include "server/net/server_counters.hpp"
#include "server/net/session_directory.hpp"
#include "server/net/view_feed.hpp"
#include "server/pipeline/token_bucket.hpp"
#include "server/pipeline/world_pipeline.hpp"
#include "voxel.pb.h"

namespace vox::net {

namespace asio = boost::asio;

class ClientSession;

// What every session shares with the server. Any thread. A session holds nothing of the
// Server itself: sessions still queued when the Server is destroyed are destroyed with
// the io_context, after it, and must not touch it. So the configuration, the gate and the
// log limit are shared, and what is referenced (counters, pipeline) outlives the
// io_context.
struct SessionServices {
  ServerCounters& counters;
  std::shared_ptr<const ServerConfig> config;
  std::shared_ptr<AdmissionGate> admission;
  std::shared_ptr<SharedLogRateLimit> logs;
  std::shared_ptr<PlayerRegistry<ClientSession>> players;     // authenticated player ids
  std::shared_ptr<SessionDirectory<ClientSession>> sessions;  // every live session
  std::shared_ptr<BanKeeper> bans;
  std::shared_ptr<LiveSettings> live;  // what a reload changes: read at each Hello
};

// Who a session's player is (an admin's player list, kicks and bans). Any thread.
struct PlayerCard {
  uint64_t session = 0;
  std::string player_id, name, address;
  auth::Role role = auth::Role::kPlayer;
  int64_t connected_unix_ms = 0;
  uint64_t edits = 0, bytes_sent = 0;
};

class ClientSession : public std::enable_shared_from_this<ClientSession>,
                      private Connection::Events {
 public:
  // `address` was admitted (AdmissionGate::connect) for this connection; the session
  // releases it when it ends.
  ClientSession(std::unique_ptr<Connection> connection, std::string address, uint64_t id,
                pipeline::WorldPipeline& pipeline, SessionServices services);
  ~ClientSession();

  void start();  // any thread, once
  void on_chunks_published(
      std::shared_ptr<const std::vector<world::ChunkCoord>> chunks);  // any thread
  // Any thread: false when none of `chunks` can be in this session's view, so the publish
  // fan-out skips it (ViewFeed::may_see).
  bool may_see(const std::vector<world::ChunkCoord>& chunks) const { return feed_.may_see(chunks); }
  // Any thread: new level-of-detail meshes; ignored without a LOD view.
  void on_lod_published(std::shared_ptr<const std::vector<pipeline::LodKey>> keys);
  bool has_lod_view() const { return feed_.has_lod_view(); }  // any thread
  // Sends an Error and closes (SHUTTING_DOWN, SERVER_FULL); any thread.
  // Any thread: a SIGHUP's edit budgets, for this player from now on (applied on the strand;
  // a token's own budget still wins).
  void reload_budget(const LiveValues& live);
  void close_with_error(wire::Error::Code code, std::string message,
                        int64_t banned_until_unix_ms = 0);
  uint64_t id() const { return id_; }
  bool is_player() const { return player_.load(std::memory_order_relaxed); }
  // Any thread: who the player is, once past Hello (nullopt before, and once told to close).
  std::optional<PlayerCard> card() const;
  // Any thread: the session's accounted memory (view map, queues, buffers), refreshed on
  // its strand.
  size_t memory_bytes() const { return memory_bytes_.load(std::memory_order_relaxed); }

 private:
  // All strand only. What the connection tells (Connection::Events).
  bool on_message(std::span<const uint8_t> body) override;
  void on_stream_error(wire::Error::Code code, const std::string& why) override;
  void on_written(size_t bytes) override;
  void on_write_timeout() override;
  void on_closed() override;
  std::shared_ptr<Connection::Events> events() {  // keeps the session alive
    return {shared_from_this(), static_cast<Connection::Events*>(this)};
  }
  void on_frame(std::span<const uint8_t> body);
  void handle_hello(const wire::Hello& hello);
  // With a key: the token's claims, or nullopt after refusing the connection.
  std::optional<auth::PlayerClaims> verify_hello_token(const wire::Hello& hello,
                                                       const auth::PublicKey& key);
  // Replaces a connection of the same id.
  void join_as(const auth::PlayerClaims& claims, const LiveValues& live);
  BudgetLimits edit_limits(const auth::PlayerClaims* claims, const LiveValues& live) const;
  void send_welcome(uint64_t players);
  void handle_set_view(const wire::SetView& view);
  using PendingView = ViewFeed::View;
  void apply_view(const PendingView& v);
  // SetView's lod_level and lod_distance into `v`; false after a BAD_VALUE error.
  bool check_lod(const wire::SetView& view, PendingView& v);
  void handle_resync(const wire::Resync& resync);
  void handle_region_command(const wire::RegionCommand& command);  // region_commands.cpp
  void list_regions(uint64_t after_id, wire::Envelope& reply);
  void handle_admin_command(const wire::AdminCommand& command);  // admin_commands.cpp
  void list_players(uint64_t after_session, wire::Envelope& reply);
  void kick(const wire::Kick& kick, wire::Envelope& reply);
  void ban(const wire::Ban& ban, wire::Envelope& reply);
  void unban(const wire::Ban& ban, wire::Envelope& reply);
  void list_bans(const std::string& cursor, wire::Envelope& reply);
  void rollback(const wire::Rollback& request, wire::Envelope& reply);
  void log_admin(const std::string& what);
  bool refuse_if_banned(const std::string& player_id, auth::Role role);
  void handle_query(const wire::Query& query);  // query_commands.cpp
  void handle_edit(const wire::Edit& edit);
  void on_edit_result(uint64_t ticket, wire::Envelope result, size_t work_chunks);
  void queue_result(uint64_t request, wire::EditResult::Status status, const std::string& reason,
                    uint32_t retry_after_ms = 0);
  void send_error(wire::Error::Code code, const std::string& message, bool close,
                  int64_t banned_until_unix_ms = 0);
  void log_refusal(wire::EditResult::Status status, const std::string& reason);
  void queue_control(const wire::Envelope& message);
  void pump();
  void arm_idle_timer();
  void drop_slow(DroppedBy why, const char* what);
  void shutdown();
  void update_memory();

  const std::unique_ptr<Connection> connection_;
  Strand& strand_;  // the connection's
  // Close: the grace an Error gets to leave before the connection closes.
  StrandTimer handshake_timer_, idle_timer_, close_timer_, read_pause_timer_, view_timer_;
  const std::string address_;  // the peer's address, as admitted
  const uint64_t id_;
  SessionServices services_;  // before config_, which refers into it
  const ServerConfig& config_;
  pipeline::WorldPipeline& pipeline_;
  ServerCounters& counters_;
  std::atomic<bool> player_{false};
  std::optional<auth::PlayerClaims> claims_;  // strand: the token it joined with (none: open)
  std::atomic<size_t> memory_bytes_{0};
  // The card's counters (written on the strand, read by any thread).
  std::atomic<uint64_t> edits_accepted_{0}, bytes_sent_{0};
  std::atomic<bool> leaving_{false};  // told to close: no card (listed, kicked) any more
  int64_t connected_unix_ms_ = 0;     // set at Hello, before player_

  std::string name_;       // as the client sent it, or the token's display name
  std::string log_name_;   // escaped, for logs
  std::string player_id_;  // the token's (empty: open server); edits are logged under it
  auth::Role role_ = auth::Role::kPlayer;
  bool closing_ = false;
  bool applying_view_ = false;  // apply_view() in progress: pump() waits for its end
  static constexpr size_t kMaxRegionCommandsInFlight = 16;
  size_t region_commands_in_flight_ = 0;  // sent to the pipeline, not yet answered
  static constexpr size_t kMaxAdminCommandsInFlight = 16;
  size_t admin_commands_in_flight_ = 0;  // bans sent to the BanKeeper, not yet answered
  EditGate edits_;  // role, validity, in-flight cap and budget of the client's edits
  pipeline::TokenBucket view_budget_, message_budget_, error_budget_;
  QueryGate queries_;  // validity, in-flight cap and rate of the client's queries
  ResultOrder results_;
  std::optional<PendingView> pending_view_;  // coalesced SetView waiting for view_budget_
  ViewFeed feed_;  // what the client sees: its view, what it holds, the next mesh
  std::deque<std::vector<uint8_t>> control_;  // serialized messages sent before meshes
  size_t control_bytes_ = 0;
};

// Closes every player connection of `target` (a player id or an address) but
// `except_session` (and admins', with `spare_admins`) with `code`; returns how many. Any
// thread.
size_t close_matching(SessionDirectory<ClientSession>& sessions, store::Ban::Kind kind,
                      const std::string& target, wire::Error::Code code, const std::string& message,
                      int64_t banned_until_unix_ms, uint64_t except_session, bool spare_admins);

}  // namespace vox::net
