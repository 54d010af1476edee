// A zone record's payload: a logged edit with its author and edit id (zone_leases.hpp).
#include "server/store/edit_codec.hpp"
#include "server/store/zone_leases.hpp"
#include "server/world/byte_io.hpp"

namespace vox::store {

namespace {
// 1: no edit id (records written before edits across holders); 2: with it.
constexpr uint8_t kEditPayloadVersion = 2;
constexpr size_t kMaxAuthor = 1024;
}  // namespace

std::vector<uint8_t> encode_zone_edit(const LoggedEdit& edit) {
  const std::string author = edit.author.substr(0, kMaxAuthor);
  return world::ByteWriter({kEditPayloadVersion})
      .u16(static_cast<uint16_t>(author.size()))
      .text(author)
      .u64(edit.edit_id)
      .bytes(encode_edit(edit.edit, edit.keep))
      .take();
}

std::optional<LoggedEdit> decode_zone_edit(const ZoneRecord& record, std::string* error) {
  const auto fail = [error](const char* why) -> std::optional<LoggedEdit> {
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
  auto decoded = decode_edit_record(r.rest(), &why);
  if (!decoded) {
    if (error) *error = "an edit record: " + why;
    return std::nullopt;
  }
  LoggedEdit out;
  out.seq = record.seq;
  out.unix_ms = record.unix_ms;
  out.author = std::move(author);
  out.edit = std::move(decoded->edit);
  out.keep = std::move(decoded->keep);
  out.edit_id = edit_id;
  return out;
}

}  // namespace vox::store
