#include "client-cli/nifti_file.hpp"

#include <bit>
#include <cmath>
#include <cstring>

namespace vox::cli {
namespace {

// Field offsets in the NIfTI-1 header (nifti1.h).
constexpr size_t kSizeofHdr = 0, kDim = 40, kDatatype = 70, kBitpix = 72, kPixdim = 76,
                 kVoxOffset = 108, kSclSlope = 112, kSclInter = 116, kMagic = 344;

class Fields {
 public:
  Fields(std::span<const uint8_t> bytes, bool swap) : p_(bytes.data()), swap_(swap) {}
  int16_t i16(size_t at) const {
    uint16_t u;
    std::memcpy(&u, p_ + at, 2);
    return static_cast<int16_t>(swap_ ? __builtin_bswap16(u) : u);
  }
  int32_t i32(size_t at) const { return static_cast<int32_t>(u32(at)); }
  float f32(size_t at) const { return std::bit_cast<float>(u32(at)); }

 private:
  uint32_t u32(size_t at) const {
    uint32_t u;
    std::memcpy(&u, p_ + at, 4);
    return swap_ ? __builtin_bswap32(u) : u;
  }
  const uint8_t* p_;
  bool swap_;
};

SampleType type_of(int16_t datatype, const std::string& path) {
  switch (datatype) {
    case 2:
      return SampleType::kU8;
    case 4:
      return SampleType::kI16;
    case 8:
      return SampleType::kI32;
    case 16:
      return SampleType::kF32;
    case 64:
      return SampleType::kF64;
    case 256:
      return SampleType::kI8;
    case 512:
      return SampleType::kU16;
    case 768:
      return SampleType::kU32;
    default:
      throw VolumeError(path + ": NIfTI datatype " + std::to_string(datatype) +
                        " is not supported (uint8, int8, uint16, int16, uint32, int32, float32, "
                        "float64 are)");
  }
}

bool is_gzip(std::span<const uint8_t> bytes) {
  return bytes.size() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b;
}

}  // namespace

NiftiHeader parse_nifti_header(std::span<const uint8_t> bytes, const std::string& path) {
  if (bytes.size() < kNiftiHeaderSize) {
    throw VolumeError(path + ": too short for a NIfTI-1 header (" + std::to_string(bytes.size()) +
                      " of 348 bytes)");
  }
  int32_t sizeof_hdr;
  std::memcpy(&sizeof_hdr, bytes.data() + kSizeofHdr, 4);
  NiftiHeader h;
  const bool native_little = std::endian::native == std::endian::little;
  if (sizeof_hdr == 348) {
    h.big_endian = !native_little;
  } else if (static_cast<int32_t>(__builtin_bswap32(static_cast<uint32_t>(sizeof_hdr))) == 348) {
    h.big_endian = native_little;
  } else if (sizeof_hdr == 540 ||
             static_cast<int32_t>(__builtin_bswap32(static_cast<uint32_t>(sizeof_hdr))) == 540) {
    throw VolumeError(path + ": NIfTI-2 files are not supported (convert to NIfTI-1)");
  } else {
    throw VolumeError(path + ": not a NIfTI-1 file (sizeof_hdr is " + std::to_string(sizeof_hdr) +
                      ", not 348)");
  }
  const Fields f(bytes, h.big_endian != !native_little);
  const char* magic = reinterpret_cast<const char*>(bytes.data() + kMagic);
  if (std::memcmp(magic, "ni1\0", 4) == 0)
    throw VolumeError(path + ": a NIfTI .hdr/.img pair is not supported (use a single .nii file)");
  if (std::memcmp(magic, "n+1\0", 4) != 0)
    throw VolumeError(path + ": NIfTI magic is not \"n+1\" (not a single-file NIfTI-1 volume)");

  const int rank = f.i16(kDim);
  if (rank < 3 || rank > 7)
    throw VolumeError(path + ": dim[0] is " + std::to_string(rank) + "; a 3-D volume is needed");
  for (int a = 0; a < 3; ++a) h.dims[a] = f.i16(kDim + 2 * (1 + a));
  for (int a = 3; a < rank; ++a) {
    const int extra = f.i16(kDim + 2 * (1 + a));
    if (extra != 1) {
      throw VolumeError(path + ": dim[" + std::to_string(a + 1) + "] is " + std::to_string(extra) +
                        "; only one 3-D volume per file is supported");
    }
  }
  check_volume_dims(path, h.dims);
  h.type = type_of(f.i16(kDatatype), path);
  const int bitpix = f.i16(kBitpix);
  if (bitpix != static_cast<int>(8 * sample_size(h.type))) {
    throw VolumeError(path + ": bitpix " + std::to_string(bitpix) + " does not match datatype " +
                      sample_type_name(h.type));
  }
  const float offset = f.f32(kVoxOffset);
  if (!(offset >= 0.0f && offset < 1e12f) || offset != std::floor(offset)) {
    throw VolumeError(path + ": vox_offset " + std::to_string(offset) + " is not a byte offset");
  }
  h.data_offset = std::max<size_t>(static_cast<size_t>(offset), kNiftiHeaderSize + 4);
  const float slope = f.f32(kSclSlope), inter = f.f32(kSclInter);
  if (std::isfinite(slope) && slope != 0.0f) {  // 0 or NaN: the samples are used as they are
    h.slope = slope;
    h.intercept = std::isfinite(inter) ? inter : 0.0;
  }
  for (int a = 0; a < 3; ++a) {
    const float s = f.f32(kPixdim + 4 * (1 + a));
    h.spacing[a] = std::isfinite(s) && s > 0.0f ? s : 0.0f;
  }
  return h;
}

LoadedVolume parse_nifti(std::span<const uint8_t> file, const std::string& path) {
  LoadedVolume loaded;
  if (!is_gzip(file)) {
    const NiftiHeader h = parse_nifti_header(file, path);
    const size_t n = volume_sample_count(h.dims);
    const size_t bytes = n * sample_size(h.type);
    if (h.data_offset > file.size() || file.size() - h.data_offset < bytes) {
      throw VolumeError(path + ": the header declares " + std::to_string(bytes) +
                        " bytes of samples at offset " + std::to_string(h.data_offset) +
                        ", the file has " + std::to_string(file.size()) + " bytes");
    }
    loaded.volume.dims = h.dims;
    loaded.volume.values.resize(n);
    decode_samples(file.subspan(h.data_offset, bytes), n, h.type, h.big_endian, h.slope,
                   h.intercept, loaded.volume.values.data(), path);
    loaded.spacing = h.spacing;
    return loaded;
  }
  GzipReader gz(file, path);
  uint8_t header[kNiftiHeaderSize];
  gz.read(header, sizeof header, "NIfTI header");
  const NiftiHeader h = parse_nifti_header(header, path);
  const size_t n = volume_sample_count(h.dims);
  const size_t bytes = n * sample_size(h.type);
  gz.check_can_hold(h.data_offset + static_cast<uint64_t>(bytes), "header and samples");
  gz.skip(h.data_offset - kNiftiHeaderSize, "NIfTI extensions");
  loaded.volume.dims = h.dims;
  read_gzip_samples(gz, n, h.type, h.big_endian, h.slope, h.intercept, loaded.volume.values, path);
  loaded.spacing = h.spacing;
  return loaded;
}

LoadedVolume read_nifti(const std::string& path) {
  const MappedFile file(path);
  return parse_nifti(file.bytes(), path);
}

}  // namespace vox::cli
