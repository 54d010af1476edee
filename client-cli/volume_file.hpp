// Reading sampled volumes for offline meshing. Four formats:
//   text (seed 002): "xdim ydim zdim" then xdim*ydim*zdim numbers, whitespace separated;
//   raw:  float32 little-endian, x fastest, then y, then z; dims given by the caller;
//   NIfTI-1 (.nii, .nii.gz) and NRRD (.nrrd, .nhdr): nifti_file.hpp, nrrd_file.hpp.
// Every problem (missing or short file, bad dims, non-numbers, NaN/inf, extra data) is a
// VolumeError whose message names the file and the problem.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include "client-cli/sample_data.hpp"
#include "server/mesh/volume_mesher.hpp"

namespace vox::cli {

struct VolumeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

inline constexpr size_t kMaxVolumeSamples = size_t{1} << 31;  // 8 GiB of float32

// A volume and, for formats that carry one, its voxel spacing (per axis; 0 where the
// file's value is not a positive finite number).
struct LoadedVolume {
  mesh::Volume volume;
  std::optional<std::array<float, 3>> spacing;
};

// Throws unless every dimension is at least 2 and the product at most kMaxVolumeSamples.
void check_volume_dims(const std::string& path, const std::array<int, 3>& dims);
size_t volume_sample_count(const std::array<int, 3>& dims);

mesh::Volume read_text_volume(const std::string& path);
// The text format from memory; error messages name `path` as the file.
mesh::Volume parse_text_volume(std::string_view text, const std::string& path);
// A raw float32 little-endian volume mapped read-only from its file: the samples without
// a copy (page-cache pages, dropped from the process when this is destroyed). Throws
// VolumeError when the file cannot be mapped or its size does not match dims. Finiteness
// is not checked here (quantize_samples does). Move-only; any thread.
class RawVolumeFile {
 public:
  RawVolumeFile(const std::string& path, std::array<int, 3> dims);

  std::span<const float> values() const;
  const std::array<int, 3>& dims() const { return dims_; }
  // Drops the pages holding only samples [begin, end) from this process's memory (they
  // stay in the page cache; reading them again maps them back). Any thread.
  void release(size_t begin, size_t end) const;

 private:
  static MappedFile checked(const std::string& path, const std::array<int, 3>& dims);
  std::array<int, 3> dims_;
  MappedFile file_;
};

// A copy of a RawVolumeFile's samples, every one checked finite.
mesh::Volume read_raw_volume(const std::string& path, std::array<int, 3> dims);
// Raw when dims are given, text otherwise.
mesh::Volume read_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims);
// Raw when dims are given; else NIfTI for .nii/.nii.gz, NRRD for .nrrd/.nhdr, text otherwise.
LoadedVolume load_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims);

// "X,Y,Z" with each a positive integer; throws VolumeError otherwise.
std::array<int, 3> parse_dims(const std::string& text);

}  // namespace vox::cli
