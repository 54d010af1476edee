// Reading sampled volumes for offline meshing. Two formats:
//   text (seed 002): "xdim ydim zdim" then xdim*ydim*zdim numbers, whitespace separated;
//   raw:  float32 little-endian, x fastest, then y, then z; dims given by the caller.
// Every problem (missing or short file, bad dims, non-numbers, NaN/inf, extra data) is a
// VolumeError whose message names the file and the problem.
#pragma once

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "server/mesh/volume_mesher.hpp"

namespace vox::cli {

struct VolumeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

inline constexpr size_t kMaxVolumeSamples = size_t{1} << 31;  // 8 GiB of float32

mesh::Volume read_text_volume(const std::string& path);
// The text format from memory; error messages name `path` as the file.
mesh::Volume parse_text_volume(std::string_view text, const std::string& path);
mesh::Volume read_raw_volume(const std::string& path, std::array<int, 3> dims);
// Raw when dims are given, text otherwise.
mesh::Volume read_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims);

// "X,Y,Z" with each a positive integer; throws VolumeError otherwise.
std::array<int, 3> parse_dims(const std::string& text);

}  // namespace vox::cli
