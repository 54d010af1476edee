// NIfTI-1 single-file volumes (.nii, and .nii.gz compressed with gzip): the 348-byte
// header (either byte order), 3-D data of type uint8/int8/uint16/int16/uint32/int32/
// float32/float64, scaled by scl_slope/scl_inter when the slope is set, and the voxel
// spacing from pixdim. NIfTI-2, the .hdr/.img pair and 4-D volumes of more than one frame
// are refused. Every problem is a VolumeError with a one-line message naming the file,
// found before the samples are allocated.
#pragma once

#include <span>
#include <string>

#include "client-cli/sample_data.hpp"
#include "client-cli/volume_file.hpp"

namespace vox::cli {

inline constexpr size_t kNiftiHeaderSize = 348;

struct NiftiHeader {
  std::array<int, 3> dims{};
  SampleType type = SampleType::kU8;
  bool big_endian = false;
  size_t data_offset = 0;  // vox_offset: where the samples start in the (decompressed) file
  double slope = 1.0, intercept = 0.0;
  std::array<float, 3> spacing{1, 1, 1};  // pixdim[1..3]; 0 when the file's is unusable
};

// The header in the first kNiftiHeaderSize bytes of `bytes`.
NiftiHeader parse_nifti_header(std::span<const uint8_t> bytes, const std::string& path);

// .nii or .nii.gz (gzip when the file starts with the gzip magic, whatever its name).
LoadedVolume read_nifti(const std::string& path);
// The same from the file's bytes.
LoadedVolume parse_nifti(std::span<const uint8_t> file, const std::string& path);

}  // namespace vox::cli
