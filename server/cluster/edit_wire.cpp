#include "server/cluster/edit_wire.hpp"

#include "server/store/edit_codec.hpp"
#include "server/world/byte_io.hpp"

namespace vox::cluster {
namespace {

constexpr uint8_t kVersion = 2;
constexpr uint8_t kRequest = 3;
constexpr uint8_t kReply = 4;
constexpr size_t kMaxText = 4096;   // an author, a message
constexpr size_t kMaxList = 65535;  // u16 counts

// A string with its u16 length first (at most kMaxText bytes of it).
void put_text(world::ByteWriter& w, const std::string& s) {
  const std::string cut = s.substr(0, kMaxText);
  w.u16(static_cast<uint16_t>(cut.size())).text(cut);
}
std::string get_text(world::ByteReader& r) {
  const size_t n = r.u16();
  if (n > kMaxText) {
    r.fail();
    return {};
  }
  return r.text(n);
}

template <typename T>
std::optional<T> fail(std::string* error, const std::string& why) {
  if (error) *error = why;
  return std::nullopt;
}

bool header(world::ByteReader& r, uint8_t kind) {
  return r.u8() == kVersion && r.u8() == kind && r.ok();
}

}  // namespace

std::vector<uint8_t> encode_edit_request(const EditRequest& r) {
  world::ByteWriter w({kVersion, kRequest});
  w.u64(r.id).u8((r.bypass_regions ? 1 : 0) | (r.part ? 2 : 0)).u64(r.edit_id);
  if (r.part) w.u64(r.part->key());
  put_text(w, r.author);
  w.bytes(store::encode_edit(r.edit));
  return w.take();
}

std::optional<EditRequest> decode_edit_request(std::span<const uint8_t> bytes, std::string* error) {
  world::ByteReader r(bytes);
  if (!header(r, kRequest)) return fail<EditRequest>(error, "not an edit request of this version");
  EditRequest out;
  out.id = r.u64();
  const uint8_t flags = r.u8();
  out.edit_id = r.u64();
  if (flags & 2) out.part = world::ZoneId::from_key(r.u64());
  out.author = get_text(r);
  if (!r.ok() || flags > 3) return fail<EditRequest>(error, "an edit request's header is damaged");
  out.bypass_regions = (flags & 1) != 0;
  std::string why;
  auto edit = store::decode_edit(r.rest(), &why);
  if (!edit) return fail<EditRequest>(error, "an edit request's edit: " + why);
  out.edit = std::move(*edit);
  return out;
}

std::vector<uint8_t> encode_edit_reply(const EditReply& r) {
  world::ByteWriter w({kVersion, kReply});
  w.u64(r.id)
      .u8(static_cast<uint8_t>(r.reason))
      .u8((r.already_applied ? 1 : 0) | (r.zone_moving ? 2 : 0));
  put_text(w, r.message);
  const size_t zones = std::min(r.zones.size(), kMaxList);
  w.u16(static_cast<uint16_t>(zones));
  for (size_t i = 0; i < zones; ++i) {
    w.u64(r.zones[i].first.key());
    w.u64(r.zones[i].second);
  }
  const size_t chunks = std::min(r.changed_chunks.size(), kMaxList);
  w.u16(static_cast<uint16_t>(chunks));
  for (size_t i = 0; i < chunks; ++i) {
    const world::ChunkCoord& c = r.changed_chunks[i];
    w.u32(static_cast<uint32_t>(c.x));
    w.u32(static_cast<uint32_t>(c.y));
    w.u32(static_cast<uint32_t>(c.z));
  }
  const size_t regions = std::min(r.clipped_by.size(), kMaxList);
  w.u16(static_cast<uint16_t>(regions));
  for (size_t i = 0; i < regions; ++i) w.u64(r.clipped_by[i]);
  return w.take();
}

std::optional<EditReply> decode_edit_reply(std::span<const uint8_t> bytes, std::string* error) {
  world::ByteReader r(bytes);
  if (!header(r, kReply)) return fail<EditReply>(error, "not an edit reply of this version");
  EditReply out;
  out.id = r.u64();
  const uint8_t reason = r.u8();
  if (reason > static_cast<uint8_t>(world::RefusalReason::kForbidden))
    return fail<EditReply>(error, "an edit reply's reason is unknown");
  out.reason = static_cast<world::RefusalReason>(reason);
  const uint8_t flags = r.u8();
  if (flags > 3) return fail<EditReply>(error, "an edit reply's flags are unknown");
  out.already_applied = (flags & 1) != 0;
  out.zone_moving = (flags & 2) != 0;
  out.message = get_text(r);
  const size_t zones = r.u16();
  for (size_t i = 0; i < zones && r.ok(); ++i) {
    const world::ZoneId zone = world::ZoneId::from_key(r.u64());
    out.zones.emplace_back(zone, r.u64());
  }
  const size_t chunks = r.u16();
  for (size_t i = 0; i < chunks && r.ok(); ++i) {
    const auto x = static_cast<int32_t>(r.u32()), y = static_cast<int32_t>(r.u32()),
               z = static_cast<int32_t>(r.u32());
    out.changed_chunks.push_back({x, y, z});
  }
  const size_t regions = r.u16();
  for (size_t i = 0; i < regions && r.ok(); ++i) out.clipped_by.push_back(r.u64());
  if (!r.done()) return fail<EditReply>(error, "an edit reply is cut or too long");
  return out;
}

}  // namespace vox::cluster
