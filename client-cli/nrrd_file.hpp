// NRRD volumes (.nrrd with the data attached, .nhdr with a detached "data file"): 3-D, of
// type uint8/int8/uint16/int16/uint32/int32/float/double, encoding raw, gzip or ascii,
// either byte order, with "line skip" and "byte skip"; the voxel spacing from "spacings"
// or the lengths of the "space directions" vectors. Every problem is a VolumeError with
// a one-line message naming the file, found before the samples are allocated.
#pragma once

#include <optional>
#include <span>
#include <string>

#include "client-cli/sample_data.hpp"
#include "client-cli/volume_file.hpp"

namespace vox::cli {

inline constexpr size_t kMaxNrrdHeaderBytes = 64 * 1024;

enum class NrrdEncoding { kRaw, kGzip, kAscii };

struct NrrdHeader {
  std::array<int, 3> dims{};
  SampleType type = SampleType::kU8;
  NrrdEncoding encoding = NrrdEncoding::kRaw;
  bool big_endian = false;
  std::optional<std::array<float, 3>> spacing;  // 0 for an axis whose spacing is unusable
  std::string data_file;                        // empty: the data follow the header
  int line_skip = 0;
  long long byte_skip = 0;  // -1: the raw data are the file's last bytes
  size_t header_bytes = 0;  // where the data start in an attached file
};

// The header at the start of `text` (up to and including its blank line).
NrrdHeader parse_nrrd_header(std::string_view text, const std::string& path);

LoadedVolume read_nrrd(const std::string& path);
// The same from the file's bytes; `path` names it in messages and locates a data file.
LoadedVolume parse_nrrd(std::span<const uint8_t> file, const std::string& path);

}  // namespace vox::cli
