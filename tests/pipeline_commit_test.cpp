// Pipelined group commit: while a batch's append is in flight the pipeline applies the
// next batches, yet nothing of a batch is published and no edit of it answered before its
// append is durable; answers keep batch order; an append that fails undoes its batch and
// every batch applied on top of it. The stores are real (SQLite, a PostgreSQL server the
// test starts); a gate in front of append_edits holds an append in flight.
#include <gtest/gtest.h>
#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <future>
#include <mutex>
#include <thread>

#include "server/pipeline/world_pipeline.hpp"
#include "server/store/world_store.hpp"
#include "tests/pipeline_test_util.hpp"
#include "tests/postgres_server.hpp"

namespace vox::pipeline {
namespace {

using namespace std::chrono_literals;

// A real store whose appends wait at a gate the test opens; counts the appends entered.
class GatedStore final : public store::WorldStore {
 public:
  explicit GatedStore(store::WorldStore& inner) : inner_(inner) {}
  const std::string& name() const override { return inner_.name(); }
  store::WorldInfo info() override { return inner_.info(); }
  void append_edits(std::span<const store::LoggedEdit> edits,
                    std::span<const SeqRange> forget) override {
    {
      std::unique_lock lock(mutex_);
      ++entered_;
      cv_.notify_all();
      cv_.wait(lock, [&] { return open_; });
    }
    inner_.append_edits(edits, forget);
  }
  void write_checkpoint(std::span<const store::ChunkRecord> chunks, uint64_t seq,
                        uint64_t trim_through) override {
    inner_.write_checkpoint(chunks, seq, trim_through);
  }
  std::optional<store::ChunkRecord> read_chunk(world::ChunkCoord c) override {
    return inner_.read_chunk(c);
  }
  void for_each_chunk(const std::function<void(world::ChunkCoord, uint64_t)>& fn) override {
    inner_.for_each_chunk(fn);
  }
  void for_each_edit(uint64_t after,
                     const std::function<bool(const store::LoggedEdit&)>& fn) override {
    inner_.for_each_edit(after, fn);
  }

  void close() {
    std::lock_guard lock(mutex_);
    open_ = false;
  }
  void open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    cv_.notify_all();
  }
  // Waits (up to 10 s) until `n` appends have reached the gate.
  bool wait_entered(int n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, 10s, [&] { return entered_ >= n; });
  }

 private:
  store::WorldStore& inner_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = true;
  int entered_ = 0;
};

using test::samples_around;

std::filesystem::path temp_world(const std::string& tag) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("voxel_pcommit_" + std::to_string(::getpid()) + "_" + tag);
  std::filesystem::remove_all(dir);
  return dir;
}

std::vector<uint64_t> logged_seqs(store::WorldStore& s) {
  std::vector<uint64_t> seqs;
  s.for_each_edit(0, [&](const store::LoggedEdit& e) {
    seqs.push_back(e.seq);
    return true;
  });
  return seqs;
}

TEST(PipelinedCommit, TheNextBatchAppliesWhileAnAppendIsInFlightAndAnswersKeepTheirOrder) {
  const auto dir = temp_world("order");
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = &store});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{-1, y / 32 - 1, -1}, {2, y / 32 + 1, 2}}).get();
  const uint64_t published = p.stats().meshes_published;
  const auto far_before = samples_around(p, 50, y, 50, 3);

  store.close();
  std::mutex order_mutex;
  std::vector<int> order;
  std::promise<EditResult> first, second;
  p.submit(world::Explosion{{10, float(y), 10}, 4, 1}, [&](const EditResult& r) {
    std::lock_guard lock(order_mutex);
    order.push_back(1);
    first.set_value(r);
  });
  ASSERT_TRUE(store.wait_entered(1));
  p.submit(world::Explosion{{50, float(y), 50}, 4, 1}, [&](const EditResult& r) {
    std::lock_guard lock(order_mutex);
    order.push_back(2);
    second.set_value(r);
  });
  // The second batch applied while the first append is held (an inspection after it sees
  // its samples), but neither is answered nor published.
  EXPECT_NE(samples_around(p, 50, y, 50, 3), far_before) << "the next batch did not apply";
  auto first_result = first.get_future();
  auto second_result = second.get_future();
  EXPECT_EQ(first_result.wait_for(50ms), std::future_status::timeout);
  EXPECT_EQ(second_result.wait_for(0ms), std::future_status::timeout);
  EXPECT_EQ(p.stats().meshes_published, published) << "a mesh was published before its append";
  EXPECT_TRUE(logged_seqs(*sqlite).empty());

  store.open();
  ASSERT_TRUE(first_result.get().accepted);
  ASSERT_TRUE(second_result.get().accepted);
  EXPECT_EQ(order, (std::vector<int>{1, 2}));
  EXPECT_GT(p.stats().meshes_published, published);
  EXPECT_EQ(logged_seqs(*sqlite).size(), 2u);
  p.stop();
  std::filesystem::remove_all(dir);
}

TEST(PipelinedCommit, ALoadBesideAnEditInFlightPublishesOnlyOnceTheEditIsDurable) {
  const auto dir = temp_world("load");
  auto sqlite = store::open_world_store(dir.string(), {.seed = 3});
  GatedStore store(*sqlite);
  WorldPipeline p(PipelineConfig{.seed = 3, .threads = 2, .store = &store});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  const world::ChunkCoord at{0, y / 32, 0};
  store.close();
  // Nothing is meshed there yet: the edit generates the chunk it touches and re-meshes
  // nothing; a load of its neighbourhood right after must not show it before it is durable.
  auto edit = p.submit(world::Explosion{{10, float(y), 10}, 6, 1});
  ASSERT_TRUE(store.wait_entered(1));
  auto load = p.load(mesh::ChunkBox{at.offset(-1, -1, -1), at.offset(1, 1, 1)});
  EXPECT_EQ(load.wait_for(200ms), std::future_status::timeout)
      << "a load published meshes showing an edit whose append had not landed";
  EXPECT_EQ(p.stats().meshes_published, 0u);
  store.open();
  ASSERT_TRUE(edit.get().accepted);
  ASSERT_EQ(load.wait_for(10s), std::future_status::ready);
  p.stop();
  std::filesystem::remove_all(dir);
}

TEST(PipelinedCommit, AFailedAppendUndoesTheBatchesAppliedOnTopOfIt) {
  test::PostgresServer server;
  auto pg = store::open_world_store(server.create_database("pipelined"), {.seed = 3});
  GatedStore store(*pg);
  WorldPipeline p(PipelineConfig{
      .seed = 3, .threads = 2, .store = &store, .store_retry = std::chrono::milliseconds(50)});
  const int y = static_cast<int>(world::TerrainGenerator(3).height_at(10, 10));
  p.load(mesh::ChunkBox{{0, y / 32 - 1, 0}, {1, y / 32 + 1, 1}}).get();
  const auto before = samples_around(p, 20, y, 20, 14);
  const uint64_t published = p.stats().meshes_published;

  store.close();
  auto a = p.submit(world::Explosion{{10, float(y), 10}, 5, 1});
  ASSERT_TRUE(store.wait_entered(1));
  auto b = p.submit(world::Explosion{{12, float(y), 12}, 5, 1});  // on top of a
  auto c = p.submit(world::Brush{{30, float(y), 30}, 4, 0.8f, true, std::nullopt});
  EXPECT_NE(samples_around(p, 20, y, 20, 14), before);  // applied, not durable yet
  server.stop();  // a's append now fails for real; b's and c's are not tried
  store.open();
  for (auto* f : {&a, &b, &c}) {
    const EditResult r = f->get();
    EXPECT_FALSE(r.accepted);
    EXPECT_EQ(r.reason, world::RefusalReason::kStorageUnavailable);
    EXPECT_TRUE(r.changed_chunks.empty());
  }
  EXPECT_EQ(samples_around(p, 20, y, 20, 14), before) << "an undone batch left samples behind";
  EXPECT_EQ(p.stats().meshes_published, published);

  server.start();
  std::this_thread::sleep_for(60ms);  // past store_retry
  const EditResult again = p.submit(world::Explosion{{12, float(y), 12}, 5, 1}).get();
  EXPECT_TRUE(again.accepted) << again.message;
  EXPECT_EQ(logged_seqs(*pg).size(), 1u) << "a refused edit is in the log";
  p.stop();
}

}  // namespace
}  // namespace vox::pipeline
