#include "server/cluster/zone_wire.hpp"

#include "server/store/edit_codec.hpp"
#include "server/world/byte_io.hpp"

namespace vox::cluster {
namespace {

constexpr uint8_t kVersion = 1;
constexpr uint8_t kRecord = 1;
constexpr uint8_t kHeartbeat = 2;

}  // namespace

bool valid_world_name(const std::string& world) {
  if (world.empty() || world.size() > 64) return false;
  for (const char c : world) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    if (!ok) return false;
  }
  return true;
}

std::string zone_subject(const std::string& world, world::ZoneId zone, const char* what) {
  return "vox." + world + ".zone." + std::to_string(zone.key()) + "." + what;
}

std::vector<uint8_t> encode_zone_record(world::ZoneId zone, const store::ZoneRecord& record) {
  return world::ByteWriter({kVersion, kRecord})
      .u64(zone.key())
      .u64(record.seq)
      .u64(static_cast<uint64_t>(record.unix_ms))
      .bytes(record.payload)
      .take();
}

std::vector<uint8_t> encode_zone_heartbeat(world::ZoneId zone, uint64_t last_seq) {
  return world::ByteWriter({kVersion, kHeartbeat}).u64(zone.key()).u64(last_seq).take();
}

std::optional<ZoneMessage> decode_zone_message(std::span<const uint8_t> bytes) {
  world::ByteReader r(bytes);
  if (r.u8() != kVersion || !r.ok()) return std::nullopt;
  const uint8_t kind = r.u8();
  ZoneMessage m;
  m.zone = world::ZoneId::from_key(r.u64());
  m.record.seq = r.u64();
  if (kind == kHeartbeat) {
    if (!r.done()) return std::nullopt;  // a heartbeat has an exact size
    m.heartbeat = true;
    return m;
  }
  m.record.unix_ms = static_cast<int64_t>(r.u64());
  const std::span<const uint8_t> payload = r.rest();
  if (kind != kRecord || !r.ok() || m.record.seq == 0) return std::nullopt;  // seqs start at 1
  m.record.payload.assign(payload.begin(), payload.end());
  return m;
}

namespace {
// 1: no edit id (records written before edits across holders); 2: with it.
constexpr uint8_t kEditPayloadVersion = 2;
constexpr size_t kMaxAuthor = 1024;
}  // namespace

std::vector<uint8_t> encode_zone_edit(const store::LoggedEdit& edit) {
  const std::string author = edit.author.substr(0, kMaxAuthor);
  return world::ByteWriter({kEditPayloadVersion})
      .u16(static_cast<uint16_t>(author.size()))
      .text(author)
      .u64(edit.edit_id)
      .bytes(store::encode_edit(edit.edit, edit.keep))
      .take();
}

std::optional<store::LoggedEdit> decode_zone_edit(const store::ZoneRecord& record,
                                                  std::string* error) {
  const auto fail = [error](const char* why) -> std::optional<store::LoggedEdit> {
    if (error) *error = why;
    return std::nullopt;
  };
  world::ByteReader r(record.payload);
  const uint8_t version = r.u8();
  const size_t length = r.u16();
  if (!r.ok()) return fail("an edit record shorter than its header");
  if (version != 1 && version != kEditPayloadVersion)
    return fail("an edit record of an unknown version");
  std::string author = length > kMaxAuthor ? std::string() : r.text(length);
  const uint64_t edit_id = version >= 2 ? r.u64() : 0;
  if (length > kMaxAuthor || !r.ok()) return fail("an edit record's author is cut");
  std::string why;
  auto decoded = store::decode_edit_record(r.rest(), &why);
  if (!decoded) {
    if (error) *error = "an edit record: " + why;
    return std::nullopt;
  }
  store::LoggedEdit out;
  out.seq = record.seq;
  out.unix_ms = record.unix_ms;
  out.author = std::move(author);
  out.edit = std::move(decoded->edit);
  out.keep = std::move(decoded->keep);
  out.edit_id = edit_id;
  return out;
}

}  // namespace vox::cluster
