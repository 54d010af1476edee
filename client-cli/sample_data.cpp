#include "client-cli/sample_data.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>
#include <vector>

#include "client-cli/volume_file.hpp"

namespace vox::cli {
namespace {

template <class T>
T load(const uint8_t* p, bool swap) {
  using U = std::conditional_t<
      sizeof(T) == 1, uint8_t,
      std::conditional_t<sizeof(T) == 2, uint16_t,
                         std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;
  U u;
  std::memcpy(&u, p, sizeof u);
  if constexpr (sizeof(T) == 2) {
    if (swap) u = __builtin_bswap16(u);
  } else if constexpr (sizeof(T) == 4) {
    if (swap) u = __builtin_bswap32(u);
  } else if constexpr (sizeof(T) == 8) {
    if (swap) u = __builtin_bswap64(u);
  }
  return std::bit_cast<T>(u);
}

template <class T>
void decode_as(const uint8_t* bytes, size_t count, bool swap, double slope, double intercept,
               float* out, const std::string& path, size_t first_index) {
  const bool identity = slope == 1.0 && intercept == 0.0;
  for (size_t i = 0; i < count; ++i) {
    const T raw = load<T>(bytes + i * sizeof(T), swap);
    const double v =
        identity ? static_cast<double>(raw) : static_cast<double>(raw) * slope + intercept;
    const float f = static_cast<float>(v);
    if (!std::isfinite(f))
      throw VolumeError(path + ": sample " + std::to_string(first_index + i) +
                        " is not finite, or too large for float32 after scaling");
    out[i] = f;
  }
}

}  // namespace

size_t sample_size(SampleType type) {
  switch (type) {
    case SampleType::kU8:
    case SampleType::kI8:
      return 1;
    case SampleType::kU16:
    case SampleType::kI16:
      return 2;
    case SampleType::kU32:
    case SampleType::kI32:
    case SampleType::kF32:
      return 4;
    case SampleType::kF64:
      return 8;
  }
  return 1;
}

const char* sample_type_name(SampleType type) {
  switch (type) {
    case SampleType::kU8:
      return "uint8";
    case SampleType::kI8:
      return "int8";
    case SampleType::kU16:
      return "uint16";
    case SampleType::kI16:
      return "int16";
    case SampleType::kU32:
      return "uint32";
    case SampleType::kI32:
      return "int32";
    case SampleType::kF32:
      return "float32";
    case SampleType::kF64:
      return "float64";
  }
  return "?";
}

void decode_samples(std::span<const uint8_t> bytes, size_t count, SampleType type, bool big_endian,
                    double slope, double intercept, float* out, const std::string& path,
                    size_t first_index) {
  if (bytes.size() / sample_size(type) < count)
    throw VolumeError(path + ": internal: fewer sample bytes than samples");
  const bool swap = big_endian != (std::endian::native == std::endian::big);
  const uint8_t* p = bytes.data();
  switch (type) {
    case SampleType::kU8:
      return decode_as<uint8_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kI8:
      return decode_as<int8_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kU16:
      return decode_as<uint16_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kI16:
      return decode_as<int16_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kU32:
      return decode_as<uint32_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kI32:
      return decode_as<int32_t>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kF32:
      return decode_as<float>(p, count, swap, slope, intercept, out, path, first_index);
    case SampleType::kF64:
      return decode_as<double>(p, count, swap, slope, intercept, out, path, first_index);
  }
}

GzipReader::GzipReader(std::span<const uint8_t> compressed, std::string path)
    : in_(compressed), path_(std::move(path)) {
  z_.next_in = const_cast<Bytef*>(in_.data());
  z_.avail_in = static_cast<uInt>(std::min<size_t>(in_.size(), UINT32_MAX));
  if (inflateInit2(&z_, 16 + MAX_WBITS) != Z_OK)
    throw VolumeError(path_ + ": cannot start gzip decompression");
}

GzipReader::~GzipReader() { inflateEnd(&z_); }

void GzipReader::read(uint8_t* out, size_t n, const char* what) {
  size_t done = 0;
  while (done < n) {
    if (ended_) {
      throw VolumeError(path_ + ": gzip data end in the " + what + ", after " +
                        std::to_string(delivered_ + done) + " decompressed bytes");
    }
    if (z_.avail_in == 0) {  // more than 4 GiB of input: feed the next part
      const size_t used = static_cast<size_t>(z_.next_in - in_.data());
      z_.avail_in = static_cast<uInt>(std::min<size_t>(in_.size() - used, UINT32_MAX));
    }
    z_.next_out = out + done;
    z_.avail_out = static_cast<uInt>(std::min<size_t>(n - done, UINT32_MAX));
    const uInt before = z_.avail_out;
    const int rc = inflate(&z_, Z_NO_FLUSH);
    done += before - z_.avail_out;
    if (rc == Z_STREAM_END) {
      // Another gzip member may follow (files written by concatenation).
      const size_t used = static_cast<size_t>(z_.next_in - in_.data());
      if (used < in_.size() && in_[used] == 0x1f) {
        if (inflateReset(&z_) != Z_OK) throw VolumeError(path_ + ": gzip reset failed");
      } else {
        ended_ = true;
      }
    } else if (rc == Z_BUF_ERROR && z_.avail_in == 0) {
      const size_t used = static_cast<size_t>(z_.next_in - in_.data());
      if (used >= in_.size()) ended_ = true;  // truncated: reported above
    } else if (rc != Z_OK) {
      throw VolumeError(path_ + ": corrupt gzip data in the " + what + " (" +
                        (z_.msg != nullptr ? z_.msg : "zlib error " + std::to_string(rc)) + ")");
    }
  }
  delivered_ += n;
}

void GzipReader::skip(size_t n, const char* what) {
  uint8_t buffer[4096];
  while (n > 0) {
    const size_t step = std::min(n, sizeof buffer);
    read(buffer, step, what);
    n -= step;
  }
}

void GzipReader::check_can_hold(uint64_t needed, const char* what) const {
  const uint64_t room = static_cast<uint64_t>(in_.size()) * kMaxDeflateRatio;
  if (needed > room) {
    throw VolumeError(path_ + ": the header declares " + std::to_string(needed) + " bytes of " +
                      what + ", more than " + std::to_string(in_.size()) +
                      " bytes of gzip data can hold");
  }
}

void read_gzip_samples(GzipReader& gz, size_t count, SampleType type, bool big_endian, double slope,
                       double intercept, std::vector<float>& out, const std::string& path) {
  constexpr size_t kSlabBytes = size_t{1} << 20;
  const size_t size = sample_size(type), per_slab = kSlabBytes / size;
  std::vector<uint8_t> slab(std::min(count, per_slab) * size);
  out.clear();
  out.reserve(std::min(count, per_slab));
  while (out.size() < count) {
    const size_t done = out.size(), k = std::min(per_slab, count - done);
    gz.read(slab.data(), k * size, "samples");
    out.resize(done + k);  // grows geometrically, only once the bytes are there
    decode_samples({slab.data(), k * size}, k, type, big_endian, slope, intercept,
                   out.data() + done, path, done);
  }
}

std::string quoted_excerpt(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  return "'" + out + (s.size() > 40 ? "...'" : "'");
}

MappedFile::MappedFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw VolumeError(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw VolumeError(path + ": not a regular file");
  }
  size_ = static_cast<size_t>(st.st_size);
  if (size_ > 0) {
    void* map = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    const int e = errno;
    ::close(fd);
    if (map == MAP_FAILED) throw VolumeError(path + ": cannot map: " + std::strerror(e));
    map_ = map;
  } else {
    ::close(fd);
  }
}

MappedFile::~MappedFile() {
  if (map_ != nullptr) ::munmap(map_, size_);
}

MappedFile::MappedFile(MappedFile&& other) noexcept
    : map_(std::exchange(other.map_, nullptr)), size_(std::exchange(other.size_, 0)) {}

void MappedFile::release(size_t begin, size_t end) const {
  static const size_t page = static_cast<size_t>(::sysconf(_SC_PAGESIZE));
  const size_t first = (begin + page - 1) / page * page;  // whole pages only
  const size_t last = std::min(end, size_) / page * page;
  if (map_ != nullptr && first < last)
    (void)::madvise(static_cast<char*>(map_) + first, last - first, MADV_DONTNEED);
}

}  // namespace vox::cli
