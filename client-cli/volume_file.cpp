#include "client-cli/volume_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include "client-cli/nifti_file.hpp"
#include "client-cli/nrrd_file.hpp"
#include "client-cli/sample_data.hpp"

namespace vox::cli {
namespace {

bool is_space(char c) {
  return c == ' ' || c == '\n' || c == '\r' || c == '\t' || c == '\f' || c == '\v';
}

class Tokens {
 public:
  explicit Tokens(std::string_view text) : p_(text.data()), end_(text.data() + text.size()) {}
  // Next token, or empty at the end of the text.
  std::string_view next() {
    while (p_ < end_ && is_space(*p_)) ++p_;
    const char* start = p_;
    while (p_ < end_ && !is_space(*p_)) ++p_;
    return {start, static_cast<size_t>(p_ - start)};
  }
  size_t remaining() const { return static_cast<size_t>(end_ - p_); }

 private:
  const char* p_;
  const char* end_;
};

bool ends_with(const std::string& s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i])
      return false;
  }
  return true;
}

}  // namespace

void check_volume_dims(const std::string& path, const std::array<int, 3>& dims) {
  size_t samples = 1;
  for (int d : dims) {
    if (d < 2)
      throw VolumeError(path + ": every dimension must be at least 2 samples, got " +
                        std::to_string(d));
    samples *= static_cast<size_t>(d);
    if (samples > kMaxVolumeSamples)
      throw VolumeError(path + ": volume too large (over 2^31 samples)");
  }
}

size_t volume_sample_count(const std::array<int, 3>& dims) {
  return static_cast<size_t>(dims[0]) * dims[1] * dims[2];
}

std::array<int, 3> parse_dims(const std::string& text) {
  std::array<int, 3> dims{};
  const char* p = text.data();
  const char* end = text.data() + text.size();
  for (int a = 0; a < 3; ++a) {
    auto [next, ec] = std::from_chars(p, end, dims[a]);
    if (ec != std::errc() || dims[a] <= 0)
      throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
    p = next;
    if (a < 2) {
      if (p == end || *p != ',')
        throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
      ++p;
    }
  }
  if (p != end)
    throw VolumeError("--dims must be X,Y,Z with positive integers, got '" + text + "'");
  return dims;
}

mesh::Volume read_text_volume(const std::string& path) {
  return parse_text_volume(read_whole_file(path), path);
}

mesh::Volume parse_text_volume(std::string_view text, const std::string& path) {
  Tokens tokens(text);
  mesh::Volume volume;
  const char* names[3] = {"xdim", "ydim", "zdim"};
  for (int a = 0; a < 3; ++a) {
    const std::string_view t = tokens.next();
    if (t.empty()) throw VolumeError(path + ": missing " + names[a] + " in the header");
    auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), volume.dims[a]);
    if (ec != std::errc() || end != t.data() + t.size()) {
      throw VolumeError(path + ": " + names[a] + " is not an integer: '" +
                        std::string(t.substr(0, 32)) + "'");
    }
  }
  check_volume_dims(path, volume.dims);
  const size_t n = volume_sample_count(volume.dims);
  // Each value takes a byte and a separator: a header may not make us allocate for more
  // values than the file can hold (17 bytes once asked for 632 MB).
  const size_t room = (tokens.remaining() + 1) / 2;
  if (n > room) {
    throw VolumeError(path + ": expected " + std::to_string(n) +
                      " values, the file has room for at most " + std::to_string(room));
  }
  volume.values.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const std::string_view t = tokens.next();
    if (t.empty()) {
      throw VolumeError(path + ": expected " + std::to_string(n) + " values, found " +
                        std::to_string(i));
    }
    float v = 0;
    const char* first = t.data() + (t.size() > 1 && t[0] == '+' ? 1 : 0);
    auto [end, ec] = std::from_chars(first, t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size()) {
      throw VolumeError(path + ": value " + std::to_string(i) + " is not a number: '" +
                        std::string(t.substr(0, 32)) + "'");
    }
    if (!std::isfinite(v))
      throw VolumeError(path + ": value " + std::to_string(i) + " is not finite");
    volume.values[i] = v;
  }
  if (!tokens.next().empty()) {
    throw VolumeError(path + ": more than the " + std::to_string(n) +
                      " values the header declares");
  }
  return volume;
}

RawVolumeFile::RawVolumeFile(const std::string& path, std::array<int, 3> dims) : dims_(dims) {
  static_assert(std::endian::native == std::endian::little,
                "raw volumes are mapped as they are: a little-endian host is assumed");
  check_volume_dims(path, dims);
  const size_t n = volume_sample_count(dims);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw VolumeError(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw VolumeError(path + ": not a regular file");
  }
  const auto size = static_cast<size_t>(st.st_size);
  if (size != n * sizeof(float)) {
    ::close(fd);
    throw VolumeError(path + ": raw float32 volume of " + std::to_string(dims[0]) + "x" +
                      std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + " needs " +
                      std::to_string(n * sizeof(float)) + " bytes, file has " +
                      std::to_string(size));
  }
  // Not populated: the mesher reads the samples in order and releases what it is done
  // with, so that only a slab of the file is resident at a time.
  void* map = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  const int e = errno;
  ::close(fd);
  if (map == MAP_FAILED) throw VolumeError(path + ": cannot map: " + std::strerror(e));
  map_ = map;
  bytes_ = size;
}

RawVolumeFile::~RawVolumeFile() {
  if (map_ != nullptr) ::munmap(map_, bytes_);
}

RawVolumeFile::RawVolumeFile(RawVolumeFile&& other) noexcept
    : dims_(other.dims_), map_(std::exchange(other.map_, nullptr)), bytes_(other.bytes_) {}

std::span<const float> RawVolumeFile::values() const {
  return {static_cast<const float*>(map_), bytes_ / sizeof(float)};
}

void RawVolumeFile::release(size_t begin, size_t end) const {
  static const size_t page = static_cast<size_t>(::sysconf(_SC_PAGESIZE));
  const size_t first = (begin * sizeof(float) + page - 1) / page * page;  // whole pages only
  const size_t last = std::min(end * sizeof(float), bytes_) / page * page;
  if (first < last) (void)::madvise(static_cast<char*>(map_) + first, last - first, MADV_DONTNEED);
}

mesh::Volume read_raw_volume(const std::string& path, std::array<int, 3> dims) {
  const RawVolumeFile file(path, dims);
  const std::span<const float> values = file.values();
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i]))
      throw VolumeError(path + ": value " + std::to_string(i) + " is not finite");
  }
  mesh::Volume volume;
  volume.dims = dims;
  volume.values.assign(values.begin(), values.end());
  return volume;
}

mesh::Volume read_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims) {
  return dims ? read_raw_volume(path, *dims) : read_text_volume(path);
}

LoadedVolume load_volume(const std::string& path, const std::optional<std::array<int, 3>>& dims) {
  if (!dims && (ends_with(path, ".nii") || ends_with(path, ".nii.gz"))) return read_nifti(path);
  if (!dims && (ends_with(path, ".nrrd") || ends_with(path, ".nhdr"))) return read_nrrd(path);
  return {read_volume(path, dims), std::nullopt};
}

}  // namespace vox::cli
