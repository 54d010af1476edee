#include "server/cluster/zone_wire.hpp"

#include "server/store/edit_codec.hpp"

namespace vox::cluster {
namespace {

constexpr uint8_t kVersion = 1;
constexpr uint8_t kRecord = 1;
constexpr uint8_t kHeartbeat = 2;
constexpr size_t kRecordHeader = 2 + 8 + 8 + 8;
constexpr size_t kHeartbeatSize = 2 + 8 + 8;

void put64(std::vector<uint8_t>& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
uint64_t get64(std::span<const uint8_t> in, size_t at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t{in[at + i]} << (8 * i);
  return v;
}

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
  std::vector<uint8_t> out{kVersion, kRecord};
  out.reserve(kRecordHeader + record.payload.size());
  put64(out, zone.key());
  put64(out, record.seq);
  put64(out, static_cast<uint64_t>(record.unix_ms));
  out.insert(out.end(), record.payload.begin(), record.payload.end());
  return out;
}

std::vector<uint8_t> encode_zone_heartbeat(world::ZoneId zone, uint64_t last_seq) {
  std::vector<uint8_t> out{kVersion, kHeartbeat};
  put64(out, zone.key());
  put64(out, last_seq);
  return out;
}

std::optional<ZoneMessage> decode_zone_message(std::span<const uint8_t> bytes) {
  if (bytes.size() < 2 || bytes[0] != kVersion) return std::nullopt;
  ZoneMessage m;
  if (bytes[1] == kHeartbeat) {
    if (bytes.size() != kHeartbeatSize) return std::nullopt;
    m.heartbeat = true;
    m.zone = world::ZoneId::from_key(get64(bytes, 2));
    m.record.seq = get64(bytes, 10);
    return m;
  }
  if (bytes[1] != kRecord || bytes.size() < kRecordHeader) return std::nullopt;
  m.zone = world::ZoneId::from_key(get64(bytes, 2));
  m.record.seq = get64(bytes, 10);
  m.record.unix_ms = static_cast<int64_t>(get64(bytes, 18));
  m.record.payload.assign(bytes.begin() + kRecordHeader, bytes.end());
  if (m.record.seq == 0) return std::nullopt;  // sequences start at 1
  return m;
}

namespace {
constexpr uint8_t kEditPayloadVersion = 1;
constexpr size_t kMaxAuthor = 1024;
}  // namespace

std::vector<uint8_t> encode_zone_edit(const store::LoggedEdit& edit) {
  const std::string& author =
      edit.author.size() > kMaxAuthor ? edit.author.substr(0, kMaxAuthor) : edit.author;
  const std::vector<uint8_t> body = store::encode_edit(edit.edit, edit.keep);
  std::vector<uint8_t> out;
  out.reserve(3 + author.size() + body.size());
  out.push_back(kEditPayloadVersion);
  out.push_back(static_cast<uint8_t>(author.size() & 0xff));
  out.push_back(static_cast<uint8_t>(author.size() >> 8));
  out.insert(out.end(), author.begin(), author.end());
  out.insert(out.end(), body.begin(), body.end());
  return out;
}

std::optional<store::LoggedEdit> decode_zone_edit(const store::ZoneRecord& record,
                                                  std::string* error) {
  const auto fail = [error](const char* why) -> std::optional<store::LoggedEdit> {
    if (error) *error = why;
    return std::nullopt;
  };
  const std::vector<uint8_t>& p = record.payload;
  if (p.size() < 3) return fail("an edit record shorter than its header");
  if (p[0] != kEditPayloadVersion) return fail("an edit record of an unknown version");
  const size_t author = p[1] | (size_t{p[2]} << 8);
  if (author > kMaxAuthor || p.size() < 3 + author) return fail("an edit record's author is cut");
  std::string why;
  auto decoded = store::decode_edit_record(std::span(p).subspan(3 + author), &why);
  if (!decoded) {
    if (error) *error = "an edit record: " + why;
    return std::nullopt;
  }
  store::LoggedEdit out;
  out.seq = record.seq;
  out.unix_ms = record.unix_ms;
  out.author.assign(reinterpret_cast<const char*>(p.data() + 3), author);
  out.edit = std::move(decoded->edit);
  out.keep = std::move(decoded->keep);
  return out;
}

}  // namespace vox::cluster
