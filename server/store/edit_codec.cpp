#include "server/store/edit_codec.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <sstream>

#include "server/world/byte_io.hpp"

namespace vox::store {
namespace {

enum Kind : uint8_t { kBrush = 0, kExplosion = 1, kSmooth = 2, kPaint = 3, kStamp = 4 };

class Writer : public world::ByteWriter {
 public:
  Writer() = default;  // no header
  explicit Writer(Kind kind) : ByteWriter({kEditFormat, kind}) {}
  Writer& vec(const world::Vec3& v) {
    f32(v.x).f32(v.y).f32(v.z);
    return *this;
  }
};

class Reader : public world::ByteReader {
 public:
  using ByteReader::ByteReader;
  world::Vec3 vec() {
    const float x = f32(), y = f32(), z = f32();
    return {x, y, z};
  }
};

struct Encode {
  std::vector<uint8_t> operator()(const world::Brush& b) const {
    const uint8_t flags = (b.remove ? 1 : 0) | (b.material ? 2 : 0);
    return Writer(kBrush)
        .vec(b.center)
        .f32(b.radius)
        .f32(b.strength)
        .u8(flags)
        .u8(b.material.value_or(0))
        .take();
  }
  std::vector<uint8_t> operator()(const world::Explosion& e) const {
    return Writer(kExplosion).vec(e.center).f32(e.radius).f32(e.power).take();
  }
  std::vector<uint8_t> operator()(const world::Smooth& s) const {
    return Writer(kSmooth).vec(s.center).f32(s.radius).f32(s.strength).take();
  }
  std::vector<uint8_t> operator()(const world::Paint& p) const {
    return Writer(kPaint).vec(p.center).f32(p.radius).u8(p.material).take();
  }
  std::vector<uint8_t> operator()(const world::Stamp& s) const {
    const bool sphere = s.shape == world::Stamp::Shape::kSphere;
    Writer w(kStamp);
    w.u8(sphere ? 1 : 0).u8(s.solid ? 1 : 0).u8(s.material);
    if (sphere) return w.vec(s.center).f32(s.radius).take();
    return w.vec(s.min).vec(s.max).take();
  }
};

std::optional<world::Edit> decode_body(uint8_t kind, Reader& r) {
  switch (kind) {
    case kBrush: {
      world::Brush b;
      b.center = r.vec();
      b.radius = r.f32();
      b.strength = r.f32();
      const uint8_t flags = r.u8(), material = r.u8();
      if (flags > 3) return std::nullopt;
      b.remove = (flags & 1) != 0;
      if (flags & 2) b.material = material;
      return b;
    }
    case kExplosion: {
      world::Explosion e;
      e.center = r.vec();
      e.radius = r.f32();
      e.power = r.f32();
      return e;
    }
    case kSmooth: {
      world::Smooth s;
      s.center = r.vec();
      s.radius = r.f32();
      s.strength = r.f32();
      return s;
    }
    case kPaint: {
      world::Paint p;
      p.center = r.vec();
      p.radius = r.f32();
      p.material = r.u8();
      return p;
    }
    case kStamp: {
      world::Stamp s;
      const uint8_t shape = r.u8(), solid = r.u8();
      if (shape > 1 || solid > 1) return std::nullopt;
      s.shape = shape ? world::Stamp::Shape::kSphere : world::Stamp::Shape::kBox;
      s.solid = solid != 0;
      s.material = r.u8();
      if (shape) {
        s.center = r.vec();
        s.radius = r.f32();
      } else {
        s.min = r.vec();
        s.max = r.vec();
      }
      return s;
    }
    default:
      return std::nullopt;
  }
}

std::string fmt_vec(const world::Vec3& v) {
  std::ostringstream o;
  o << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return o.str();
}

}  // namespace

std::vector<uint8_t> encode_edit(const world::Edit& edit, std::span<const world::VoxelBox> keep) {
  std::vector<uint8_t> out = std::visit(Encode{}, edit);
  if (keep.empty()) return out;
  out[0] = kClippedEditFormat;
  const size_t n = std::min(keep.size(), kMaxKeepBoxes);  // callers stay below it
  Writer w;
  w.u16(static_cast<uint16_t>(n));
  for (size_t i = 0; i < n; ++i)
    for (const auto& corner : {keep[i].lo, keep[i].hi})
      for (const int32_t v : corner) w.i32(v);
  const std::vector<uint8_t> tail = w.take();
  out.insert(out.end(), tail.begin(), tail.end());
  return out;
}

std::optional<EditRecord> decode_edit_record(std::span<const uint8_t> bytes, std::string* error) {
  auto fail = [error](const char* why) -> std::optional<EditRecord> {
    if (error) *error = why;
    return std::nullopt;
  };
  if (bytes.size() < 2) return fail("edit record shorter than its header");
  if (bytes[0] != kEditFormat && bytes[0] != kClippedEditFormat)
    return fail("edit record of an unknown format");
  Reader r(bytes.subspan(2));
  auto edit = decode_body(bytes[1], r);
  if (!edit) return fail("edit record of an unknown kind or with a bad field");
  EditRecord record{std::move(*edit), {}};
  if (bytes[0] == kClippedEditFormat) {
    const uint16_t n = r.u16();
    if (n == 0 || n > kMaxKeepBoxes) return fail("clipped edit record with a bad box count");
    record.keep.resize(n);
    for (world::VoxelBox& box : record.keep) {
      for (int32_t& v : box.lo) v = r.i32();
      for (int32_t& v : box.hi) v = r.i32();
      for (int a = 0; a < 3; ++a)
        if (box.lo[a] > box.hi[a]) return fail("clipped edit record with an inverted box");
    }
  }
  if (!r.done()) return fail("edit record of the wrong length");
  return record;
}

std::optional<world::Edit> decode_edit(std::span<const uint8_t> bytes, std::string* error) {
  auto record = decode_edit_record(bytes, error);
  if (!record) return std::nullopt;
  return std::move(record->edit);
}

namespace {
void put_varint(std::vector<uint8_t>& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<uint8_t>(v) | 0x80);
    v >>= 7;
  }
  out.push_back(static_cast<uint8_t>(v));
}
std::optional<uint64_t> get_varint(std::span<const uint8_t> in, size_t& at) {
  uint64_t v = 0;
  for (int shift = 0; shift < 64 && at < in.size(); shift += 7) {
    const uint8_t b = in[at++];
    if (shift == 63 && b > 1) return std::nullopt;  // past 64 bits
    v |= static_cast<uint64_t>(b & 0x7f) << shift;
    if ((b & 0x80) == 0) return v;
  }
  return std::nullopt;
}
}  // namespace

std::vector<uint8_t> encode_seq_list(std::span<const uint64_t> seqs) {
  std::vector<uint8_t> out{kRollbackFormat};
  out.reserve(2 + seqs.size() * 2);
  put_varint(out, seqs.size());
  uint64_t last = 0;
  for (const uint64_t s : seqs) put_varint(out, s - last), last = s;
  return out;
}

std::optional<std::vector<uint64_t>> decode_seq_list(std::span<const uint8_t> bytes,
                                                     std::string* error) {
  const auto fail = [&](const char* why) -> std::optional<std::vector<uint64_t>> {
    if (error) *error = why;
    return std::nullopt;
  };
  if (bytes.empty() || bytes[0] != kRollbackFormat) return fail("not a rollback record");
  size_t at = 1;
  const auto n = get_varint(bytes, at);
  if (!n || *n == 0 || *n > kMaxRollbackSeqs || *n > bytes.size())
    return fail("a rollback record's count is out of range");
  std::vector<uint64_t> seqs;
  seqs.reserve(*n);
  uint64_t last = 0;
  for (uint64_t i = 0; i < *n; ++i) {
    const auto gap = get_varint(bytes, at);
    if (!gap || *gap == 0 || *gap > UINT64_MAX - last)
      return fail("a rollback record's sequence numbers are not ascending");
    seqs.push_back(last += *gap);
  }
  if (at != bytes.size()) return fail("a rollback record has bytes past its end");
  return seqs;
}

std::string describe_edit(const world::Edit& edit) {
  std::ostringstream o;
  if (const auto* b = std::get_if<world::Brush>(&edit)) {
    o << "brush at " << fmt_vec(b->center) << " r " << b->radius << " strength " << b->strength
      << (b->remove ? " remove" : " add");
    if (b->material) o << " material " << int{*b->material};
  } else if (const auto* e = std::get_if<world::Explosion>(&edit)) {
    o << "explosion at " << fmt_vec(e->center) << " r " << e->radius << " power " << e->power;
  } else if (const auto* s = std::get_if<world::Smooth>(&edit)) {
    o << "smooth at " << fmt_vec(s->center) << " r " << s->radius << " strength " << s->strength;
  } else if (const auto* p = std::get_if<world::Paint>(&edit)) {
    o << "paint at " << fmt_vec(p->center) << " r " << p->radius << " material "
      << int{p->material};
  } else {
    const auto& st = std::get<world::Stamp>(edit);
    o << "stamp " << (st.solid ? "solid " : "air ");
    if (st.shape == world::Stamp::Shape::kSphere)
      o << "sphere at " << fmt_vec(st.center) << " r " << st.radius;
    else
      o << "box " << fmt_vec(st.min) << ".." << fmt_vec(st.max);
    if (st.solid) o << " material " << int{st.material};
  }
  return o.str();
}

}  // namespace vox::store
