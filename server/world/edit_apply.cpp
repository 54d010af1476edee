#include "server/world/edit_apply.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "server/world/region.hpp"

namespace vox::world {
namespace {

// Where one edit applies: its touched box, the chunk, and what it must leave as it is.
struct Target {
  VoxelBox box;
  ChunkCoord c;
  Chunk& chunk;
  std::span<const VoxelBox> keep;
  VolumeTally* tally;  // null: not counted
};

constexpr Material kDefaultFill = 2;  // dirt, for a brush adding without a material
constexpr float kStampRamp = 0.5f;    // density per voxel across a stamp's boundary

float falloff_smooth(float d2, float r2) {
  const float u = 1.0f - d2 / r2;
  return u * u;
}

float dist2(const Vec3& c, int x, int y, int z) {
  const float dx = static_cast<float>(x) - c.x, dy = static_cast<float>(y) - c.y,
              dz = static_cast<float>(z) - c.z;
  return dx * dx + dy * dy + dz * dz;
}

// Calls fn(x, y, z, sample) -> new sample for every sample of chunk c from lo to hi
// (local) for which kept(x, y, z) is false; writes and records the changes. Edits that
// reach no protected region pass a constant false, which the compiler drops.
template <class Kept, class Fn>
ChangedBox map_samples(const int (&lo)[3], const int (&hi)[3], const int32_t (&o)[3], Chunk& chunk,
                       VolumeTally* tally, Kept&& kept, Fn&& fn) {
  ChangedBox changed;
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y)
      for (int x = lo[0]; x <= hi[0]; ++x) {
        if (kept(x, y, z)) continue;
        const Sample old = chunk.at(x, y, z);
        const Sample now = fn(o[0] + x, o[1] + y, o[2] + z, old);
        if (now == old) continue;
        if (tally) tally->add(old, now);
        chunk.set(x, y, z, now);
        changed.add(x, y, z);
      }
  return changed;
}

// Up to this many keep boxes meet a chunk, each sample is tested against each; more (a
// field of small regions), they are drawn into a bit per sample first.
constexpr size_t kKeepBoxesTested = 8;

template <class Fn>
ChangedBox for_each_sample(const Target& t, Fn&& fn) {
  const int32_t o[3] = {t.c.x * kChunkSize, t.c.y * kChunkSize, t.c.z * kChunkSize};
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0, t.box.lo[a] - o[a]);
    hi[a] = std::min(kChunkSize - 1, t.box.hi[a] - o[a]);
    if (lo[a] > hi[a]) return {};
  }
  const VoxelBox here{{o[0] + lo[0], o[1] + lo[1], o[2] + lo[2]},
                      {o[0] + hi[0], o[1] + hi[1], o[2] + hi[2]}};
  // The keep boxes that meet this chunk's part, in local coordinates.
  std::vector<VoxelBox> keep;
  for (const VoxelBox& k : t.keep) {
    if (!boxes_intersect(k, here)) continue;
    VoxelBox local = box_intersection(k, here);
    for (int a = 0; a < 3; ++a) local.lo[a] -= o[a], local.hi[a] -= o[a];
    keep.push_back(local);
  }
  ChangedBox changed;
  if (keep.empty()) {
    changed = map_samples(
        lo, hi, o, t.chunk, t.tally, [](int, int, int) { return false; }, fn);
  } else if (keep.size() <= kKeepBoxesTested) {
    changed = map_samples(
        lo, hi, o, t.chunk, t.tally,
        [&keep](int x, int y, int z) {
          return std::any_of(keep.begin(), keep.end(), [&](const VoxelBox& k) {
            return x >= k.lo[0] && x <= k.hi[0] && y >= k.lo[1] && y <= k.hi[1] && z >= k.lo[2] &&
                   z <= k.hi[2];
          });
        },
        fn);
  } else {
    std::vector<uint64_t> mask(kChunkVolume / 64, 0);  // bit x + 32 (y + 32 z)
    for (const VoxelBox& k : keep)
      for (int z = k.lo[2]; z <= k.hi[2]; ++z)
        for (int y = k.lo[1]; y <= k.hi[1]; ++y)
          for (int x = k.lo[0]; x <= k.hi[0]; ++x) {
            const int i = x + kChunkSize * (y + kChunkSize * z);
            mask[i >> 6] |= uint64_t{1} << (i & 63);
          }
    changed = map_samples(
        lo, hi, o, t.chunk, t.tally,
        [&mask](int x, int y, int z) {
          const int i = x + kChunkSize * (y + kChunkSize * z);
          return ((mask[i >> 6] >> (i & 63)) & 1) != 0;
        },
        fn);
  }
  if (changed.changed) t.chunk.compact();
  return changed;
}

Sample with_density(Sample old, float d) {
  Sample s{quantize_density(d), old.material};
  if (!is_solid(s.density)) s.material = kAir;
  return s;
}

float box_sdf(const Stamp& s, int x, int y, int z) {
  const float p[3] = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
  const float lo[3] = {s.min.x, s.min.y, s.min.z}, hi[3] = {s.max.x, s.max.y, s.max.z};
  float outside2 = 0, inside = -INFINITY;
  for (int a = 0; a < 3; ++a) {
    const float q = std::fabs(p[a] - 0.5f * (lo[a] + hi[a])) - 0.5f * (hi[a] - lo[a]);
    if (q > 0) outside2 += q * q;
    inside = std::max(inside, q);
  }
  return std::sqrt(outside2) + std::min(inside, 0.0f);
}

}  // namespace

Sample SampleSnapshot::at(int32_t x, int32_t y, int32_t z) const {
  const int32_t nx = box.hi[0] - box.lo[0] + 1, ny = box.hi[1] - box.lo[1] + 1;
  return samples[static_cast<size_t>(x - box.lo[0]) +
                 static_cast<size_t>(nx) * (static_cast<size_t>(y - box.lo[1]) +
                                            static_cast<size_t>(ny) * (z - box.lo[2]))];
}

SampleSnapshot take_snapshot(const ChunkMap& map, const VoxelBox& box) {
  SampleSnapshot snap;
  snap.box = box;
  snap.samples.reserve(static_cast<size_t>(box.hi[0] - box.lo[0] + 1) *
                       (box.hi[1] - box.lo[1] + 1) * (box.hi[2] - box.lo[2] + 1));
  for (int32_t z = box.lo[2]; z <= box.hi[2]; ++z)
    for (int32_t y = box.lo[1]; y <= box.hi[1]; ++y)
      for (int32_t x = box.lo[0]; x <= box.hi[0]; ++x)
        snap.samples.push_back(map.sample_at(x, y, z));
  return snap;
}

VoxelBox smooth_read_box(const Smooth& s) {
  VoxelBox b = touched_box(Edit{s});
  for (int a = 0; a < 3; ++a) {
    --b.lo[a];
    ++b.hi[a];
  }
  return b;
}

void ChangedBox::add(int x, int y, int z) {
  changed = true;
  const int p[3] = {x, y, z};
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::min(lo[a], p[a]);
    hi[a] = std::max(hi[a], p[a]);
  }
}

namespace {

// One function per edit kind: each maps every sample of chunk c inside the edit's box.
ChangedBox apply_brush(const Brush& b, const Target& t) {
  const float r2 = b.radius * b.radius, sign = b.remove ? -1.0f : 1.0f;
  return for_each_sample(t, [&](int x, int y, int z, Sample old) {
    const float d2 = dist2(b.center, x, y, z);
    if (d2 >= r2) return old;
    Sample s = with_density(
        old, dequantize_density(old.density) + sign * b.strength * falloff_smooth(d2, r2));
    if (is_solid(s.density) && !b.remove) {
      if (b.material)
        s.material = *b.material;
      else if (!is_solid(old.density) || old.material == kAir)
        s.material = kDefaultFill;
    }
    return s;
  });
}

ChangedBox apply_explosion(const Explosion& e, const Target& t) {
  return for_each_sample(t, [&](int x, int y, int z, Sample old) {
    const float d = std::sqrt(dist2(e.center, x, y, z));
    if (d >= e.radius) return old;
    const float u = 1.0f - d / e.radius;
    return with_density(old, dequantize_density(old.density) - e.power * u * u);
  });
}

// Reads the pre-edit `snapshot`, so the result does not depend on the chunks' order.
ChangedBox apply_smooth(const Smooth& sm, const Target& t, const SampleSnapshot& snapshot) {
  const float r2 = sm.radius * sm.radius;
  return for_each_sample(t, [&](int x, int y, int z, Sample old) {
    const float d2 = dist2(sm.center, x, y, z);
    if (d2 >= r2) return old;
    float sum = 0;
    Sample densest{kDensityMin, kAir};
    // The columns a neighbour is read from: any, or (zones) those of this sample's zone.
    int32_t x_lo = x - 1, x_hi = x + 1, z_lo = z - 1, z_hi = z + 1;
    if (snapshot.zone_chunks > 0) {
      const int64_t side = int64_t{snapshot.zone_chunks} * kChunkSize;
      const auto first = [side](int32_t v) {  // the zone's first column at or below v
        return static_cast<int32_t>((v >= 0 ? v / side : -((-int64_t{v} - 1) / side) - 1) * side);
      };
      const int32_t zx = first(x), zz = first(z);
      x_lo = std::max(x_lo, zx);
      x_hi = static_cast<int32_t>(std::min<int64_t>(x_hi, zx + side - 1));
      z_lo = std::max(z_lo, zz);
      z_hi = static_cast<int32_t>(std::min<int64_t>(z_hi, zz + side - 1));
    }
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Sample n =
              snapshot.at(std::clamp(x + dx, x_lo, x_hi), y + dy, std::clamp(z + dz, z_lo, z_hi));
          sum += dequantize_density(n.density);
          if (n.density > densest.density) densest = n;
        }
    const float before = dequantize_density(snapshot.at(x, y, z).density);
    Sample s =
        with_density(old, before + sm.strength * falloff_smooth(d2, r2) * (sum / 27.0f - before));
    if (is_solid(s.density) && s.material == kAir)
      s.material = densest.material == kAir ? kDefaultFill : densest.material;
    return s;
  });
}

ChangedBox apply_paint(const Paint& p, const Target& t) {
  const float r2 = p.radius * p.radius;
  return for_each_sample(t, [&](int x, int y, int z, Sample old) {
    if (!is_solid(old.density) || dist2(p.center, x, y, z) >= r2) return old;
    return Sample{old.density, p.material};
  });
}

ChangedBox apply_stamp(const Stamp& st, const Target& t) {
  return for_each_sample(t, [&](int x, int y, int z, Sample old) {
    const float sdf = st.shape == Stamp::Shape::kSphere
                          ? std::sqrt(dist2(st.center, x, y, z)) - st.radius
                          : box_sdf(st, x, y, z);
    const float shape = std::clamp(-sdf * kStampRamp, -1.0f, 1.0f);
    const float before = dequantize_density(old.density);
    if (st.solid) {
      if (shape <= before) return old;
      Sample s = with_density(old, shape);
      if (is_solid(s.density)) s.material = st.material;
      return s;
    }
    if (-shape >= before) return old;
    return with_density(old, -shape);
  });
}

}  // namespace

ChangedBox apply_edit(const Edit& edit, ChunkCoord c, Chunk& chunk, const SampleSnapshot* snapshot,
                      std::span<const VoxelBox> keep, VolumeTally* tally) {
  const Target t{touched_box(edit), c, chunk, keep, tally};
  struct Dispatch {
    const Target& t;
    const SampleSnapshot* snapshot;
    ChangedBox operator()(const Brush& b) const { return apply_brush(b, t); }
    ChangedBox operator()(const Explosion& e) const { return apply_explosion(e, t); }
    ChangedBox operator()(const Smooth& s) const { return apply_smooth(s, t, *snapshot); }
    ChangedBox operator()(const Paint& p) const { return apply_paint(p, t); }
    ChangedBox operator()(const Stamp& s) const { return apply_stamp(s, t); }
  };
  return std::visit(Dispatch{t, snapshot}, edit);
}

void append_dirty_chunks(ChunkCoord c, const ChangedBox& changed, std::vector<ChunkCoord>& out) {
  if (!changed.changed) return;
  int from[3], to[3];
  for (int a = 0; a < 3; ++a) {
    from[a] = changed.lo[a] <= 1 ? -1 : 0;
    to[a] = changed.hi[a] >= kChunkSize - 1 ? 1 : 0;
  }
  for (int dz = from[2]; dz <= to[2]; ++dz)
    for (int dy = from[1]; dy <= to[1]; ++dy)
      for (int dx = from[0]; dx <= to[0]; ++dx) out.push_back(c.offset(dx, dy, dz));
}

std::vector<ChunkCoord> chunks_overlapping(const VoxelBox& box) {
  const ChunkCoord lo = chunk_of_voxel(box.lo[0], box.lo[1], box.lo[2]);
  const ChunkCoord hi = chunk_of_voxel(box.hi[0], box.hi[1], box.hi[2]);
  std::vector<ChunkCoord> out;
  for_each_chunk_in(lo, hi, [&out](ChunkCoord c) { out.push_back(c); });
  return out;
}

}  // namespace vox::world
