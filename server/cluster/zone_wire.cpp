#include "server/cluster/zone_wire.hpp"

#include "server/world/byte_io.hpp"

namespace vox::cluster {
namespace {

constexpr uint8_t kVersion = 1;
constexpr uint8_t kRecord = 1;
constexpr uint8_t kHeartbeat = 2;
constexpr uint8_t kRegions = 3;

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

std::string regions_subject(const std::string& world) { return "vox." + world + ".regions"; }

std::vector<uint8_t> encode_regions_version(uint64_t version) {
  return world::ByteWriter({kVersion, kRegions}).u64(version).take();
}

std::optional<uint64_t> decode_regions_version(std::span<const uint8_t> bytes) {
  world::ByteReader r(bytes);
  const bool ours = r.u8() == kVersion && r.u8() == kRegions;
  const uint64_t version = r.u64();
  if (!ours || !r.done()) return std::nullopt;
  return version;
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

}  // namespace vox::cluster
