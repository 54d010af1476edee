#include "server/cluster/edit_wire.hpp"

#include "server/store/edit_codec.hpp"

namespace vox::cluster {
namespace {

constexpr uint8_t kVersion = 1;
constexpr uint8_t kRequest = 3;
constexpr uint8_t kReply = 4;
constexpr size_t kMaxText = 4096;   // an author, a message
constexpr size_t kMaxList = 65535;  // u16 counts

class Writer {
 public:
  explicit Writer(uint8_t kind) : out_{kVersion, kind} {}
  void u8(uint8_t v) { out_.push_back(v); }
  void u16(size_t v) {
    out_.push_back(static_cast<uint8_t>(v & 0xff));
    out_.push_back(static_cast<uint8_t>((v >> 8) & 0xff));
  }
  void u32(uint32_t v) {
    for (int i = 0; i < 4; ++i) out_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
  void u64(uint64_t v) {
    for (int i = 0; i < 8; ++i) out_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
  void text(const std::string& s) {
    const size_t n = std::min(s.size(), kMaxText);
    u16(n);
    out_.insert(out_.end(), s.begin(), s.begin() + static_cast<std::ptrdiff_t>(n));
  }
  void bytes(const std::vector<uint8_t>& b) { out_.insert(out_.end(), b.begin(), b.end()); }
  std::vector<uint8_t> take() { return std::move(out_); }

 private:
  std::vector<uint8_t> out_;
};

// Reads from the front; any read past the end sets `bad` and yields zeros.
class Reader {
 public:
  explicit Reader(std::span<const uint8_t> in) : in_(in) {}
  bool bad = false;
  uint8_t u8() { return need(1) ? in_[at_++] : 0; }
  size_t u16() {
    if (!need(2)) return 0;
    const size_t v = in_[at_] | (size_t{in_[at_ + 1]} << 8);
    at_ += 2;
    return v;
  }
  uint32_t u32() {
    if (!need(4)) return 0;
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t{in_[at_ + i]} << (8 * i);
    at_ += 4;
    return v;
  }
  uint64_t u64() {
    if (!need(8)) return 0;
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t{in_[at_ + i]} << (8 * i);
    at_ += 8;
    return v;
  }
  std::string text() {
    const size_t n = u16();
    if (n > kMaxText || !need(n)) {
      bad = true;
      return {};
    }
    std::string s(reinterpret_cast<const char*>(in_.data() + at_), n);
    at_ += n;
    return s;
  }
  std::span<const uint8_t> rest() {
    const auto r = in_.subspan(at_);
    at_ = in_.size();
    return r;
  }
  bool done() const { return !bad && at_ == in_.size(); }

 private:
  bool need(size_t n) {
    if (in_.size() - at_ >= n) return true;
    bad = true;
    return false;
  }
  std::span<const uint8_t> in_;
  size_t at_ = 0;
};

template <typename T>
std::optional<T> fail(std::string* error, const std::string& why) {
  if (error) *error = why;
  return std::nullopt;
}

bool header(Reader& r, uint8_t kind) { return r.u8() == kVersion && r.u8() == kind && !r.bad; }

}  // namespace

std::vector<uint8_t> encode_edit_request(const EditRequest& r) {
  Writer w(kRequest);
  w.u64(r.id);
  w.u8(r.bypass_regions ? 1 : 0);
  w.text(r.author);
  w.bytes(store::encode_edit(r.edit));
  return w.take();
}

std::optional<EditRequest> decode_edit_request(std::span<const uint8_t> bytes, std::string* error) {
  Reader r(bytes);
  if (!header(r, kRequest)) return fail<EditRequest>(error, "not an edit request of this version");
  EditRequest out;
  out.id = r.u64();
  const uint8_t flags = r.u8();
  out.author = r.text();
  if (r.bad || flags > 1) return fail<EditRequest>(error, "an edit request's header is damaged");
  out.bypass_regions = flags == 1;
  std::string why;
  auto edit = store::decode_edit(r.rest(), &why);
  if (!edit) return fail<EditRequest>(error, "an edit request's edit: " + why);
  out.edit = std::move(*edit);
  return out;
}

std::vector<uint8_t> encode_edit_reply(const EditReply& r) {
  Writer w(kReply);
  w.u64(r.id);
  w.u8(static_cast<uint8_t>(r.reason));
  w.text(r.message);
  const size_t zones = std::min(r.zones.size(), kMaxList);
  w.u16(zones);
  for (size_t i = 0; i < zones; ++i) {
    w.u64(r.zones[i].first.key());
    w.u64(r.zones[i].second);
  }
  const size_t chunks = std::min(r.changed_chunks.size(), kMaxList);
  w.u16(chunks);
  for (size_t i = 0; i < chunks; ++i) {
    const world::ChunkCoord& c = r.changed_chunks[i];
    w.u32(static_cast<uint32_t>(c.x));
    w.u32(static_cast<uint32_t>(c.y));
    w.u32(static_cast<uint32_t>(c.z));
  }
  const size_t regions = std::min(r.clipped_by.size(), kMaxList);
  w.u16(regions);
  for (size_t i = 0; i < regions; ++i) w.u64(r.clipped_by[i]);
  return w.take();
}

std::optional<EditReply> decode_edit_reply(std::span<const uint8_t> bytes, std::string* error) {
  Reader r(bytes);
  if (!header(r, kReply)) return fail<EditReply>(error, "not an edit reply of this version");
  EditReply out;
  out.id = r.u64();
  const uint8_t reason = r.u8();
  if (reason > static_cast<uint8_t>(world::RefusalReason::kForbidden))
    return fail<EditReply>(error, "an edit reply's reason is unknown");
  out.reason = static_cast<world::RefusalReason>(reason);
  out.message = r.text();
  const size_t zones = r.u16();
  for (size_t i = 0; i < zones && !r.bad; ++i) {
    const world::ZoneId zone = world::ZoneId::from_key(r.u64());
    out.zones.emplace_back(zone, r.u64());
  }
  const size_t chunks = r.u16();
  for (size_t i = 0; i < chunks && !r.bad; ++i) {
    const auto x = static_cast<int32_t>(r.u32()), y = static_cast<int32_t>(r.u32()),
               z = static_cast<int32_t>(r.u32());
    out.changed_chunks.push_back({x, y, z});
  }
  const size_t regions = r.u16();
  for (size_t i = 0; i < regions && !r.bad; ++i) out.clipped_by.push_back(r.u64());
  if (!r.done()) return fail<EditReply>(error, "an edit reply is cut or too long");
  return out;
}

}  // namespace vox::cluster
