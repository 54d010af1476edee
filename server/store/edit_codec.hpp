// The edit log's record of one edit: its parameters in a few tens of bytes, enough to
// apply it again bit for bit (the floats are stored exactly). Decoding never trusts the
// bytes: a record of an unknown kind, a wrong length or a bad enum value is an error.
//
// Layout (little-endian): u8 format (1), u8 kind (0 brush, 1 explosion, 2 smooth, 3 paint,
// 4 stamp), then per kind:
//   brush      f32 cx cy cz, f32 radius, f32 strength, u8 flags (1 remove, 2 has material),
//              u8 material                                                       (23 bytes)
//   explosion  f32 cx cy cz, f32 radius, f32 power                               (20 bytes)
//   smooth     f32 cx cy cz, f32 radius, f32 strength                            (20 bytes)
//   paint      f32 cx cy cz, f32 radius, u8 material                             (17 bytes)
//   stamp      u8 shape (0 box, 1 sphere), u8 solid, u8 material, then a box's f32 min xyz,
//              max xyz, or a sphere's f32 cx cy cz, radius                  (27 or 19 bytes)
// Format 2 is an edit clipped by protected regions: format 1's bytes (with format 2 in
// the first byte), then u16 n (1..4096) and n boxes of samples it left as they were, each
// i32 min xyz, max xyz (inclusive).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "server/world/edit.hpp"

namespace vox::store {

inline constexpr uint8_t kEditFormat = 1;
inline constexpr uint8_t kClippedEditFormat = 2;
inline constexpr size_t kMaxKeepBoxes = 4096;  // world::RegionLimits::max_regions

struct EditRecord {
  world::Edit edit;
  std::vector<world::VoxelBox> keep;  // samples the edit left as they were (regions)
};

// Format 1, or 2 when `keep` is not empty (at most kMaxKeepBoxes of it).
std::vector<uint8_t> encode_edit(const world::Edit& edit,
                                 std::span<const world::VoxelBox> keep = {});
// nullopt and `error` set when the bytes are not a record this version writes.
std::optional<EditRecord> decode_edit_record(std::span<const uint8_t> bytes,
                                             std::string* error = nullptr);
// The edit of a record, without what it was clipped by (tests, descriptions).
std::optional<world::Edit> decode_edit(std::span<const uint8_t> bytes,
                                       std::string* error = nullptr);

// A rollback record's sequence numbers (the `undoes` column of `rollbacks`): u8 format (3),
// then LEB128 varints: the count (1..kMaxRollbackSeqs), the first seq, and each next one's
// gap from the one before (at least 1: ascending, no repeats).
inline constexpr uint8_t kRollbackFormat = 3;
inline constexpr size_t kMaxRollbackSeqs = 1'000'000;
std::vector<uint8_t> encode_seq_list(std::span<const uint64_t> seqs);
// nullopt and `error` set when the bytes are not such a list.
std::optional<std::vector<uint64_t>> decode_seq_list(std::span<const uint8_t> bytes,
                                                     std::string* error = nullptr);

// One line for people: "brush at (1, 2, 3) r 4 strength 0.5 add material 3".
std::string describe_edit(const world::Edit& edit);

}  // namespace vox::store
