// The sample bytes of scanner volume files (NIfTI-1, NRRD): the sample types those formats
// declare, their conversion to float with a linear scaling, and gzip-compressed data read
// with checks that run before anything is allocated.
#pragma once

#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace vox::cli {

enum class SampleType : uint8_t { kU8, kI8, kU16, kI16, kU32, kI32, kF32, kF64 };

size_t sample_size(SampleType type);
const char* sample_type_name(SampleType type);

// out[i] = value i * slope + intercept for `count` samples stored in `bytes` (big-endian
// when `big_endian`). A result that is not finite (a NaN in the file, an overflowing
// scale) throws VolumeError naming `path` and the sample's index (first_index + i).
void decode_samples(std::span<const uint8_t> bytes, size_t count, SampleType type, bool big_endian,
                    double slope, double intercept, float* out, const std::string& path,
                    size_t first_index = 0);

// Deflate cannot expand a byte more than about 1032 times: a header that declares more
// samples than its compressed data could hold is refused before allocating for them.
inline constexpr uint64_t kMaxDeflateRatio = 1032;

// A gzip stream (one or more members) held in memory, read in order. Which thread: any,
// one at a time. Every problem is a VolumeError naming the file.
class GzipReader {
 public:
  GzipReader(std::span<const uint8_t> compressed, std::string path);
  ~GzipReader();
  GzipReader(const GzipReader&) = delete;
  GzipReader& operator=(const GzipReader&) = delete;

  // Fills out[0, n); throws if the data ends first (`what` names what was being read).
  void read(uint8_t* out, size_t n, const char* what);
  // Reads and drops n bytes.
  void skip(size_t n, const char* what);
  // Throws when more than `needed` decompressed bytes can not come from this stream.
  void check_can_hold(uint64_t needed, const char* what) const;

 private:
  std::span<const uint8_t> in_;
  std::string path_;
  z_stream z_{};
  bool ended_ = false;
  uint64_t delivered_ = 0;  // decompressed bytes handed out so far
};

// decode_samples() for `count` samples read from `gz`, a slab at a time, appended to
// `out`, which grows as the data arrive: a header that declares more than its stream holds
// costs the memory of what the stream does hold, not of what it declares.
void read_gzip_samples(GzipReader& gz, size_t count, SampleType type, bool big_endian, double slope,
                       double intercept, std::vector<float>& out, const std::string& path);

// A file's text for a one-line message: at most 40 characters, anything not printable
// ASCII shown as '?', in single quotes ("...'" when cut).
std::string quoted_excerpt(std::string_view s);

// A regular file mapped read-only: its bytes without reading them all (a header says how
// many are needed; a sparse 100 GiB data file costs nothing until read). Throws VolumeError
// naming the file when it cannot be opened, is not a regular file (a FIFO or /dev/zero
// never ends) or cannot be mapped. Truncating the file while it is mapped ends the process
// with SIGBUS, as for any mapped input. Move-only; any thread.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(MappedFile&& other) noexcept;
  MappedFile& operator=(MappedFile&&) = delete;
  MappedFile(const MappedFile&) = delete;

  std::span<const uint8_t> bytes() const { return {static_cast<const uint8_t*>(map_), size_}; }
  // Drops the whole pages inside bytes [begin, end) from this process's memory (they stay
  // in the page cache; reading them maps them back).
  void release(size_t begin, size_t end) const;

 private:
  void* map_ = nullptr;
  size_t size_ = 0;
};

}  // namespace vox::cli
