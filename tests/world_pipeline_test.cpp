#include "server/pipeline/world_pipeline.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <future>
#include <map>
#include <random>
#include <thread>

#include "proto/mesh_codec.hpp"
#include "tests/mesh_test_util.hpp"

namespace vox::pipeline {
namespace {

using world::ChunkCoord;
using world::kChunkSize;

constexpr uint64_t kSeed = 17;
#ifdef VOXEL_SANITIZED
constexpr int kSlow = 6;  // sanitizer builds run several times slower
#else
constexpr int kSlow = 1;
#endif

// A 3x3x3-chunk box around the surface of seed kSeed near the origin.
mesh::ChunkBox surface_box() {
  const world::TerrainGenerator gen(kSeed);
  const int cy =
      world::floor_div(static_cast<int>(std::floor(gen.height_at(48, 48))), kChunkSize) - 1;
  return {{0, cy, 0}, {2, cy + 2, 2}};
}

// Random edits of every type inside the box, a third of them centred on chunk faces,
// edges and corners.
std::vector<world::Edit> random_edits(const mesh::ChunkBox& box, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<world::Edit> edits;
  for (size_t k = 0; k < n; ++k) {
    const int lo[3] = {box.lo.x, box.lo.y, box.lo.z};
    float c[3];
    for (int a = 0; a < 3; ++a) {
      c[a] = static_cast<float>(lo[a] * kChunkSize) + unit(rng) * 3 * kChunkSize;
      if (k % 3 == 0)
        c[a] = static_cast<float>((lo[a] + 1 + static_cast<int>(rng() % 2)) * kChunkSize) - 0.5f +
               unit(rng);
    }
    const world::Vec3 at{c[0], c[1], c[2]};
    const float r = 1.5f + unit(rng) * 6;
    switch (k % 6) {
      case 0:
        edits.push_back(
            world::Brush{at, r, 0.2f + unit(rng), false, world::Material(1 + rng() % 4)});
        break;
      case 1:
        edits.push_back(world::Brush{at, r, 0.2f + unit(rng), true, std::nullopt});
        break;
      case 2:
        edits.push_back(world::Explosion{at, r + 2, 0.5f + unit(rng)});
        break;
      case 3:
        edits.push_back(world::Smooth{at, r, 0.3f + 0.7f * unit(rng)});
        break;
      case 4:
        edits.push_back(world::Paint{at, r, world::Material(1 + rng() % 4)});
        break;
      default: {
        world::Stamp s;
        s.shape = (k / 6) % 2 ? world::Stamp::Shape::kSphere : world::Stamp::Shape::kBox;
        s.center = at;
        s.radius = r;
        s.min = {c[0] - r, c[1] - r / 2, c[2] - r};
        s.max = {c[0] + r, c[1] + r / 2, c[2] + r};
        s.solid = (k / 12) % 2 == 0;
        s.material = 4;
        edits.push_back(s);
      }
    }
  }
  return edits;
}

std::vector<EditResult> apply_all(WorldPipeline& p, const std::vector<world::Edit>& edits) {
  std::vector<std::future<EditResult>> futures;
  for (const auto& e : edits) futures.push_back(p.submit(e));
  std::vector<EditResult> results;
  for (auto& f : futures) results.push_back(f.get());
  return results;
}

std::vector<mesh::ChunkMesh> published_meshes(const WorldPipeline& p, const mesh::ChunkBox& box) {
  std::vector<mesh::ChunkMesh> out;
  for (size_t i = 0; i < box.count(); ++i) {
    const MeshVersionPtr m = p.meshes().get(box.at(i));
    EXPECT_TRUE(m) << "no mesh for chunk " << i;
    out.push_back(m ? *proto::decode_mesh(m->encoding) : mesh::ChunkMesh{});  // as a client sees it
  }
  return out;
}

TEST(WorldPipeline, PublishedMeshesEqualReferenceAfterRandomEdits) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  const auto results = apply_all(p, random_edits(box, 90, 5));
  for (const auto& r : results) ASSERT_TRUE(r.accepted) << r.message;
  const auto chunked = test::world_triangles(published_meshes(p, box), box);
  std::vector<test::Triangle> reference;
  p.inspect([&](const world::ChunkMap& map) {
    reference = test::reference_marching_cubes(
        [&](int x, int y, int z) { return map.sample_at(x, y, z).density; },
        {box.lo.x * 32, box.lo.y * 32, box.lo.z * 32},
        {(box.hi.x + 1) * 32, (box.hi.y + 1) * 32, (box.hi.z + 1) * 32});
  });
  ASSERT_GT(reference.size(), 100u);
  EXPECT_EQ(chunked.size(), reference.size());
  EXPECT_EQ(test::unmatched_triangles(chunked, reference, 1e-4f), 0u);
  EXPECT_EQ(test::unmatched_triangles(reference, chunked, 1e-4f), 0u);
}

// Densities and meshes of the box and its margin after the edits, for comparison.
struct WorldImage {
  std::vector<world::Sample> samples;
  std::vector<mesh::ChunkMesh> meshes;
};
WorldImage run_with_threads(int threads, const std::vector<world::Edit>& edits,
                            const mesh::ChunkBox& box) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = threads});
  p.load(box).get();
  apply_all(p, edits);
  WorldImage image;
  image.meshes = published_meshes(p, box);
  p.inspect([&](const world::ChunkMap& map) {
    for (int z = box.lo.z * 32 - 32; z < (box.hi.z + 2) * 32; ++z)
      for (int y = box.lo.y * 32 - 32; y < (box.hi.y + 2) * 32; ++y)
        for (int x = box.lo.x * 32 - 32; x < (box.hi.x + 2) * 32; ++x)
          image.samples.push_back(map.sample_at(x, y, z));
  });
  return image;
}

TEST(WorldPipeline, SameEditsGiveIdenticalWorldWhateverTheThreadCount) {
  const mesh::ChunkBox box = surface_box();
  const auto edits = random_edits(box, 60, 9);
  const WorldImage one = run_with_threads(1, edits, box);
  for (int threads : {2, 4}) {
    const WorldImage other = run_with_threads(threads, edits, box);
    EXPECT_TRUE(one.samples == other.samples) << threads << " threads";
    ASSERT_EQ(one.meshes.size(), other.meshes.size());
    for (size_t i = 0; i < one.meshes.size(); ++i) {
      EXPECT_TRUE(one.meshes[i].positions == other.meshes[i].positions &&
                  one.meshes[i].indices == other.meshes[i].indices &&
                  one.meshes[i].normals == other.meshes[i].normals &&
                  one.meshes[i].materials == other.meshes[i].materials)
          << "chunk " << i << " with " << threads << " threads";
    }
  }
}

TEST(WorldPipeline, RefusedEditChangesNothingAndSaysWhy) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  const uint64_t before = p.meshes().get(box.at(13))->version;
  const EditResult r = p.submit(world::Explosion{{48, std::nanf(""), 48}, 8, 2}).get();
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.reason, world::RefusalReason::kNotFinite);
  EXPECT_TRUE(r.changed_chunks.empty());
  const EditResult big = p.submit(world::Explosion{{48, 0, 48}, 100, 2}).get();
  EXPECT_EQ(big.reason, world::RefusalReason::kBadRadius);
  EXPECT_EQ(p.meshes().get(box.at(13))->version, before);
  EXPECT_EQ(p.stats().edits_refused, 2u);
}

TEST(WorldPipeline, EditReportsOnlyTheChunksWhoseMeshChanged) {
  std::vector<std::vector<ChunkCoord>> notified;  // outlives the pipeline that writes it
  std::mutex m;
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  p.subscribe([&](const std::vector<ChunkCoord>& changed) {
    std::lock_guard lock(m);
    notified.push_back(changed);
  });
  // A surface point at least 5 samples away from every chunk face.
  const world::TerrainGenerator gen(kSeed);
  int x = 0, z = 0;
  float h = 0;
  bool found = false;
  for (int i = 0; i < 40 * 40 && !found; ++i) {
    x = 16 + 32 * (i % 40);
    z = 16 + 32 * (i / 40);
    h = gen.height_at(x, z);
    const int local_y = world::floor_mod(static_cast<int>(std::floor(h)), 32);
    found = local_y >= 5 && local_y <= 26;
  }
  ASSERT_TRUE(found);
  const ChunkCoord c = world::chunk_of_voxel(x, static_cast<int>(std::floor(h)), z);
  p.load({c, c}).get();
  const uint64_t before = p.meshes().get(c)->version;
  const EditResult r =
      p.submit(world::Brush{{static_cast<float>(x), h, static_cast<float>(z)}, 2, 1.0f}).get();
  ASSERT_TRUE(r.accepted);
  ASSERT_EQ(r.changed_chunks.size(), 1u);
  EXPECT_EQ(r.changed_chunks[0], c);
  EXPECT_GT(p.meshes().get(c)->version, before);
  p.inspect([](const world::ChunkMap&) {});  // the next batch: this one's subscribers have run
  std::lock_guard lock(m);
  ASSERT_FALSE(notified.empty());
  EXPECT_EQ(notified.back(), std::vector<ChunkCoord>{c});
}

TEST(WorldPipeline, EditThatChangesNoMeshPublishesNothing) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  p.load({{0, -8, 0}, {0, -8, 0}}).get();  // deep rock
  const uint64_t before = p.meshes().get({0, -8, 0})->version;
  const EditResult r = p.submit(world::Brush{{16, -8 * 32 + 16, 16}, 4, 1.0f}).get();
  EXPECT_TRUE(r.accepted);
  EXPECT_TRUE(r.changed_chunks.empty());
  EXPECT_EQ(p.meshes().get({0, -8, 0})->version, before);
  EXPECT_EQ(p.meshes().get({0, -8, 0})->triangles, 0u);
}

TEST(WorldPipeline, LoadsOnDemandAndReportsMemory) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  for (size_t i = 0; i < box.count(); ++i) EXPECT_TRUE(p.meshes().get(box.at(i)));
  const PipelineStats s = p.stats();
  EXPECT_EQ(s.loaded_chunks, 125u);  // the box and its one-chunk margin
  EXPECT_EQ(s.mesh_count, 27u);
  EXPECT_GT(s.chunk_bytes, 0u);
  EXPECT_GT(s.mesh_bytes, 0u);
}

TEST(WorldPipeline, EvictsUnusedUnmodifiedChunksButKeepsModifiedOnes) {
  WorldPipeline p(
      PipelineConfig{.seed = kSeed, .threads = 2, .evict_after = std::chrono::milliseconds(0)});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  const world::TerrainGenerator gen(kSeed);
  const EditResult r = p.submit(world::Explosion{{48, gen.height_at(48, 48), 48}, 6, 2}).get();
  ASSERT_TRUE(r.accepted);
  p.submit(world::Paint{{0, 0, 0}, 1, 2}).get();  // one more batch: eviction runs after each
  size_t modified_kept = 0;
  p.inspect([&](const world::ChunkMap& map) {
    for (const auto& [c, chunk] : map) modified_kept += chunk.is_uniform() ? 0 : 1;
  });
  const PipelineStats s = p.stats();
  EXPECT_GT(s.chunks_evicted, 0u);
  EXPECT_GT(s.modified_chunks, 0u);
  EXPECT_EQ(s.loaded_chunks, s.modified_chunks);
  EXPECT_GT(modified_kept, 0u);
}

TEST(WorldPipeline, ConcurrentWritersAndReadersSeeConsistentVersions) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();
  std::atomic<bool> done{false};
  std::atomic<size_t> reads{0};
  auto reader = [&] {
    std::map<size_t, uint64_t> seen;
    while (!done.load()) {
      for (size_t i = 0; i < box.count(); ++i) {
        const MeshVersionPtr m = p.meshes().get(box.at(i));
        ASSERT_TRUE(m);
        EXPECT_GE(m->version, seen[i]) << "a reader saw a version go back";
        seen[i] = m->version;
        const auto decoded = proto::decode_mesh(m->encoding);
        ASSERT_TRUE(decoded.ok() && decoded->triangle_count() == m->triangles);
        ++reads;
      }
    }
  };
  std::vector<std::thread> threads;
  threads.emplace_back(reader);
  threads.emplace_back(reader);
  std::vector<std::thread> writers;
  std::atomic<size_t> accepted{0};
  for (uint32_t w = 0; w < 4; ++w) {
    writers.emplace_back([&, w] {
      for (const auto& r : apply_all(p, random_edits(box, 50, 100 + w))) accepted += r.accepted;
    });
  }
  for (auto& t : writers) t.join();
  done = true;
  for (auto& t : threads) t.join();
  EXPECT_EQ(accepted.load(), 200u);
  EXPECT_GT(reads.load(), 0u);
  EXPECT_EQ(p.stats().edits_applied, 200u);
}

// A big cold load is split into groups and edits go first in every batch: an edit queued
// right behind the load gets its result while most of the load is still to come, and the
// load's completion still runs exactly once, with every chunk of the box meshed.
// An edit where no one has a mesh generates only the chunks it touches (27 for the
// largest box), not their neighbours' neighbours (343): those meshes are made when a view
// loads them. Where meshes exist, the dirtied ones are re-meshed with their neighbours.
TEST(WorldPipeline, AnEditWhereNothingIsMeshedGeneratesOnlyWhatItTouches) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const world::TerrainGenerator gen(kSeed);
  const float x = 100000, y = gen.height_at(100000, 0);
  const world::Stamp box{
      world::Stamp::Shape::kBox, {x + 2, y - 28, 2}, {x + 62, y + 28, 62}, {}, 1, true, 3};
  const EditResult far = p.submit(box).get();
  ASSERT_TRUE(far.accepted);
  EXPECT_LE(far.chunks_generated, 27u);
  EXPECT_TRUE(far.changed_chunks.empty()) << "no one holds a mesh there";
  // A view then loads the area: the edited chunks are meshed with the edit in them.
  const ChunkCoord c =
      world::chunk_of_voxel(static_cast<int32_t>(x) + 32, static_cast<int32_t>(y), 32);
  p.load({c.offset(-1, -1, -1), c.offset(1, 1, 1)}).get();
  const MeshVersionPtr mesh = p.meshes().get(c);
  ASSERT_TRUE(mesh);
  world::ChunkMap reference;
  p.inspect([&](const world::ChunkMap& map) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const ChunkCoord n = c.offset(dx, dy, dz);
          if (const world::Chunk* chunk = map.find(n)) reference.insert(n, *chunk);
        }
  });
  EXPECT_EQ(proto::decode_mesh(mesh->encoding)->indices,
            mesh::mesh_chunks(reference, {c, c})[0].indices);
  // An edit next to meshed chunks re-meshes them (and loads what that needs).
  const EditResult near = p.submit(world::Explosion{{x + 40, y, 40}, 4, 2}).get();  // in the box
  EXPECT_FALSE(near.changed_chunks.empty());
}

// Regression: batches with edits but no loads never dropped the column heights their
// edits computed, so far edits grew an unaccounted cache without bound.
TEST(WorldPipeline, EditOnlyBatchesKeepNoColumnHeights) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const world::TerrainGenerator gen(kSeed);
  for (int i = 0; i < 20; ++i) {
    const float x = 50000.0f + static_cast<float>(i) * 200;
    ASSERT_TRUE(
        p.submit(world::Brush{{x, gen.height_at(static_cast<int>(x), 0), 0}, 3, 1}).get().accepted);
  }
  p.inspect([](const world::ChunkMap&) {});  // the last edit's batch has ended
  EXPECT_EQ(p.stats().cached_columns, 0u);
}

TEST(WorldPipeline, EditsDoNotWaitBehindABigLoad) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  const mesh::ChunkBox small = surface_box();
  const mesh::ChunkBox big{small.lo.offset(-4, -4, -4), small.hi.offset(4, 4, 4)};  // 11^3 chunks
  std::atomic<int> completions{0};
  std::promise<void> loaded;
  p.load(big, [&] {
    if (completions.fetch_add(1) == 0) loaded.set_value();
  });
  auto load_done = loaded.get_future();
  const world::TerrainGenerator gen(kSeed);
  const EditResult r = p.submit(world::Brush{{48, gen.height_at(48, 48), 48}, 3, 1}).get();
  EXPECT_TRUE(r.accepted);
  EXPECT_EQ(load_done.wait_for(std::chrono::seconds(0)), std::future_status::timeout)
      << "the edit waited for the whole load";
  load_done.wait();
  p.load(small).get();  // one more round trip: nothing runs the completion twice
  EXPECT_EQ(completions.load(), 1);
  for (size_t i = 0; i < big.count(); ++i) EXPECT_TRUE(p.meshes().get(big.at(i))) << i;
}

// Edits still queued when stop() comes are all refused kShuttingDown, none applied; an
// edit submitted after it is refused at once. The pipeline thread is held in an inspection
// while the edits queue, so which edits are queued does not depend on timing.
TEST(WorldPipeline, StopRefusesWhatIsStillQueued) {
  auto p = std::make_unique<WorldPipeline>(PipelineConfig{.seed = kSeed, .threads = 1});
  const mesh::ChunkBox box = surface_box();
  std::promise<void> inspecting, release;
  std::thread holder([&] {
    p->inspect([&](const world::ChunkMap&) {
      inspecting.set_value();
      release.get_future().wait();
    });
  });
  inspecting.get_future().wait();
  std::vector<std::future<EditResult>> queued;
  for (const auto& e : random_edits(box, 30, 3)) queued.push_back(p->submit(e));
  std::thread stopper([&] { p->stop(); });
  // stop() has begun once an edit is answered on the submitting thread instead of queued
  // (polling: stop() sets its flag on the other thread, and nothing reports it).
  std::vector<std::future<EditResult>> probes;
  const auto deadline = Clock::now() + std::chrono::seconds(10 * kSlow);
  bool stopping = false;
  while (!stopping && Clock::now() < deadline) {
    probes.push_back(p->submit(world::Brush{{0, 0, 0}, 2, 1}));
    stopping = probes.back().wait_for(std::chrono::seconds(0)) == std::future_status::ready;
    if (!stopping) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  release.set_value();
  stopper.join();
  holder.join();
  ASSERT_TRUE(stopping) << "stop() never took effect";
  size_t refused = 0, applied = 0;
  for (auto& f : queued) {
    const EditResult r = f.get();
    applied += r.accepted ? 1 : 0;
    refused += r.reason == world::RefusalReason::kShuttingDown ? 1 : 0;
  }
  EXPECT_EQ(applied, 0u) << "edits queued at the stop were applied";
  EXPECT_EQ(refused, queued.size());
  for (auto& f : probes) EXPECT_EQ(f.get().reason, world::RefusalReason::kShuttingDown);
  EXPECT_EQ(p->stats().edits_applied, 0u);
  const EditResult late = p->submit(world::Brush{{0, 0, 0}, 2, 1}).get();
  EXPECT_EQ(late.reason, world::RefusalReason::kShuttingDown);
}

// Regression: an edit queued behind more than 4,096 load tasks (20 radius-12 views, about
// 143,000 chunks) once waited over 30 s. Every queued edit is in the next batch, so it
// waits at most for the load pass in flight.
TEST(WorldPipeline, EditBehindTwentyHugeViewsCompletesInBoundedTime) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  for (LoadOwner o = 1; o <= 20; ++o)
    p.set_view(o, {static_cast<int32_t>(o) * 1000, 0, 0}, 12);  // far apart, cold
  EXPECT_GT(p.stats().queued_load_chunks, 4096u);
  const world::TerrainGenerator gen(kSeed);
  const auto start = std::chrono::steady_clock::now();
  const EditResult r = p.submit(world::Brush{{48, gen.height_at(48, 48), 48}, 3, 1}).get();
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_TRUE(r.accepted);
  EXPECT_LT(took, std::chrono::seconds(2 * kSlow)) << "the edit waited behind the loads";
  EXPECT_GT(p.stats().queued_load_chunks, 4096u) << "most of the views were still queued";
  for (LoadOwner o = 1; o <= 20; ++o) p.drop_view(o);
}

// Regression: a burst of far-apart views from a client that then disconnects queued
// chunk loads that were never cancelled (5 GB). A newer view replaces the owner's queued
// one, and dropping the owner leaves nothing queued.
// Found by review: a view set while a batch ran had its request taken by that batch's
// load pass (its chunks were meshed already: nothing to do) while eviction still saw the
// views of the batch's start, so the chunks were evicted and no one loaded them again;
// with strictly nearest-first sending the session then waited for them for good.
TEST(WorldPipeline, AViewSetDuringABatchProtectsItsChunksFromThatBatchsEviction) {
  using namespace std::chrono_literals;
  // Chunks in no view are evicted once unused for 1 s: the box survives until the view
  // is set (well within that), and the blocked batch ends after it.
  WorldPipeline p(
      PipelineConfig{.seed = kSeed, .threads = 2, .evict_after = 1000ms, .evict_min_age = 0ms});
  const mesh::ChunkBox box = surface_box();
  p.load(box).get();  // one-off load: meshed, in no view
  const world::ChunkCoord centre = box.at(box.count() / 2);
  std::promise<void> entered, release;
  std::thread blocker([&] {
    p.inspect([&](const world::ChunkMap&) {  // holds the pipeline inside a batch
      entered.set_value();
      release.get_future().wait();
    });
  });
  entered.get_future().wait();
  p.set_view(5, centre, 1);             // arrives mid-batch
  std::this_thread::sleep_for(1200ms);  // older than evict_after when the batch ends
  release.set_value();
  blocker.join();
  p.inspect([](const world::ChunkMap&) {});  // the batch (and its eviction) is over
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const world::ChunkCoord c = centre.offset(dx, dy, dz);
        if (dx * dx + dy * dy + dz * dz > 1) continue;
        EXPECT_TRUE(p.meshes().get(c)) << "evicted while in a view";
      }
}

// Two views share chunks on fresh terrain; the one that planned them moves away before
// their terrain lands. The other found them waiting (nothing for it to load) and must
// still get them: they were dropped with the first view, and its view never completed.
TEST(WorldPipeline, AChunkTwoViewsWaitForIsMeshedWhenTheViewThatPlannedItLeaves) {
  for (int attempt = 0; attempt < 5; ++attempt) {
    WorldPipeline p(PipelineConfig{
        .seed = kSeed, .threads = 2, .load_work_per_owner = 0, .generate_threads = 1});
    auto next_pass = [&p] {  // the second batch from now starts after a load pass was taken
      p.inspect([](const world::ChunkMap&) {});
      p.inspect([](const world::ChunkMap&) {});
    };
    const world::TerrainGenerator gen(kSeed);
    const int32_t x = 300 + attempt * 50;
    const int32_t y = world::floor_div(static_cast<int>(gen.height_at(x * 32, x * 32)), kChunkSize);
    const world::ChunkCoord centre{x, y, x};
    p.set_view(1, centre, 2);
    next_pass();  // view 1 planned its chunks; their terrain is on its way
    p.set_view(2, centre.offset(1, 0, 0), 2);
    next_pass();                    // view 2 found most of them waiting
    p.set_view(1, {-x, y, -x}, 0);  // and view 1 leaves before they are meshed
    const std::vector<world::ChunkCoord> wanted = ball_nearest_first(centre.offset(1, 0, 0), 2);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20 * kSlow);
    size_t missing = wanted.size(), waiting = 1;
    while ((missing > 0 || waiting > 0) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      missing = std::count_if(wanted.begin(), wanted.end(),
                              [&](world::ChunkCoord c) { return !p.meshes().get(c); });
      waiting = p.stats().meshes_waiting;  // view 1's new chunk too, until its terrain lands
    }
    ASSERT_EQ(missing, 0u) << "attempt " << attempt << ": chunks of view 2 never meshed";
    EXPECT_EQ(waiting, 0u) << "a waiting chunk never meshed";
  }
}

TEST(WorldPipeline, ViewFloodThenDropLeavesNoQueuedWork) {
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2});
  for (int i = 0; i < 200; ++i) p.set_view(1, {i * 1000, 0, -i * 1000}, 12);
  EXPECT_LE(p.stats().queued_load_chunks, 7153u) << "one pending view per owner";
  EXPECT_EQ(p.stats().load_owners, 1u);
  p.drop_view(1);
  EXPECT_EQ(p.stats().queued_load_chunks, 0u);
  p.inspect([](const world::ChunkMap&) {});  // a batch boundary: nothing more is loaded
  const size_t loaded = p.stats().loaded_chunks;
  p.inspect([](const world::ChunkMap&) {});
  EXPECT_EQ(p.stats().loaded_chunks, loaded);
}

// The accounted memory never passes the budget by more than 10 %: chunks that left every
// view are evicted to make room for the new ones. One view moves to six far places.
TEST(WorldPipeline, StaysWithinItsMemoryBudgetWhileAViewMovesFar) {
  const size_t budget = 24u << 20;
  WorldPipeline p(PipelineConfig{.seed = kSeed,
                                 .threads = 2,
                                 .evict_min_age = std::chrono::milliseconds(0),
                                 .load_work_per_owner = 0,  // memory is under test, not budgets
                                 .max_memory = budget});
  const world::TerrainGenerator gen(kSeed);
  size_t peak = 0;
  for (int i = 0; i < 6; ++i) {
    const int32_t x = i * 40;  // surface views (non-uniform chunks), 40 chunks apart
    const int32_t y = world::floor_div(static_cast<int>(gen.height_at(x * 32, 0)), kChunkSize);
    p.set_view(1, {x, y, 0}, 3);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20 * kSlow);
    for (;;) {
      const PipelineStats s = p.stats();
      peak = std::max(peak, s.accounted_bytes);
      const bool loaded =
          s.queued_load_chunks == 0 && s.meshes_waiting == 0 && s.chunks_generating == 0;
      if (loaded || std::chrono::steady_clock::now() > deadline) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // sampling the figure
    }
    p.inspect([](const world::ChunkMap&) {});  // the last pass is published
    ASSERT_EQ(p.stats().queued_load_chunks, 0u) << "view " << i << " never finished loading";
    ASSERT_EQ(p.stats().meshes_waiting, 0u) << "view " << i << " never finished meshing";
    peak = std::max(peak, p.stats().accounted_bytes);
  }
  EXPECT_LE(peak, budget + budget / 10);
  EXPECT_GT(p.stats().chunks_evicted, 0u) << "the old views' chunks made room";
}

// Memory held elsewhere (sessions) fills the budget: loads wait, edits that need new
// chunks are refused SERVER_BUSY, and both resume once the memory is released.
TEST(WorldPipeline, LoadsWaitAndEditsInNewAreasAreRefusedWhileTheBudgetIsFull) {
  const size_t budget = 64u << 20;
  WorldPipeline p(PipelineConfig{.seed = kSeed, .threads = 2, .max_memory = budget});
  p.set_session_bytes(budget);
  auto loaded = p.load({{5000, 0, 5000}, {5001, 1, 5001}});
  EXPECT_EQ(loaded.wait_for(std::chrono::milliseconds(600)), std::future_status::timeout)
      << "a load waits while memory is full";
  EXPECT_TRUE(p.stats().loads_blocked);
  const EditResult r = p.submit(world::Brush{{-90000, 10, 90000}, 3, 1}).get();
  EXPECT_EQ(r.reason, world::RefusalReason::kServerBusy);
  p.set_session_bytes(0);
  EXPECT_EQ(loaded.wait_for(std::chrono::seconds(10 * kSlow)), std::future_status::ready);
  p.inspect([](const world::ChunkMap&) {});  // a batch boundary: the budget was re-checked
  EXPECT_FALSE(p.stats().loads_blocked);
  EXPECT_TRUE(p.submit(world::Brush{{-90000, 10, 90000}, 3, 1}).get().accepted);
}

// Heavy edits at far places modify chunks that cannot be evicted: once they fill the
// budget, edits needing new chunks are refused, and the total stays under 110 %.
TEST(WorldPipeline, HeavyEditsAtFarPlacesStayWithinTheMemoryBudget) {
  const size_t budget = 96u << 20;
  WorldPipeline p(PipelineConfig{.seed = kSeed,
                                 .threads = 2,
                                 .evict_min_age = std::chrono::milliseconds(0),
                                 .max_memory = budget});
  const world::TerrainGenerator gen(kSeed);
  size_t busy = 0, peak = 0;
  for (int i = 0; i < 300 && busy < 3; ++i) {
    const float x = static_cast<float>(i * 300);
    const float y = gen.height_at(static_cast<int>(x), 0);
    const EditResult r =
        p
            .submit(world::Stamp{
                world::Stamp::Shape::kBox, {x, y - 30, 0}, {x + 63, y + 30, 63}, {}, 1, true, 3})
            .get();
    if (!r.accepted) {
      EXPECT_EQ(r.reason, world::RefusalReason::kServerBusy);
      ++busy;
    }
    peak = std::max(peak, p.stats().accounted_bytes);
  }
  EXPECT_EQ(busy, 3u) << "edits needing new chunks are refused once memory is full";
  EXPECT_GT(p.stats().modified_chunks * 96 * 1024, budget / 3) << "room was made for edits";
  EXPECT_LE(peak, budget + budget / 10);
}

}  // namespace
}  // namespace vox::pipeline
